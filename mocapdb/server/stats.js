// mocapdb serve, the summary: hours and motions per source format and rate, annotated hours per label
// (bars), and the files the latest ingest refused, where the database keeps an ingest log (/api/stats).
(function () {
  const { $, api, el, cell, duration } = serve;

  function bars(box, rows, name, colors) {
    const most = Math.max(...rows.map((r) => r.hours), 1e-12);
    for (const r of rows) {
      const label = el("div", null, name(r));
      const bar = el("div", "bar");
      bar.style.width = `${(r.hours / most) * 100}%`;
      if (colors && colors[r.label]) bar.style.background = colors[r.label];
      bar.dataset.hours = String(r.hours);
      bar.title = `${r.hours.toFixed(3)} h`;
      // hours with two decimals say nothing about a small archive: the duration as it reads best
      const num = el("div", "num", `${duration(r.hours * 3600)} · ${r.motions} motion(s)` +
                     (r.segments !== undefined ? ` · ${r.segments} segment(s)` : ""));
      box.append(label, bar, num);
    }
  }

  async function main() {
    const s = await api("/api/stats");
    $("totals").textContent = `${s.motions} motion(s), ${s.hours.toFixed(2)} hours in all (${duration(s.hours * 3600)})`;
    $("totals").dataset.hours = String(s.hours);
    bars($("formats"), s.formats, (r) => `${r.format} · ${Number(r.source_fps).toFixed(0)} Hz`);
    $("labels-title").textContent = `Annotated hours per label (model ${s.model})`;
    if (s.labels.length) bars($("labels"), s.labels, (r) => r.label, s.colors);
    else $("labels").textContent = s.annotated_models.length ?
      `no stored annotations of model ${s.model} (models with some: ${s.annotated_models.join(", ")})` :
      "no stored annotations: run mocapdb annotate";
    if (s.refused) {
      $("refused-box").hidden = false;
      const n = {};
      for (const r of s.refused) n[r.outcome] = (n[r.outcome] || 0) + 1;
      $("refused-summary").textContent = s.refused.length ?
        Object.entries(n).map(([k, v]) => `${v} ${k}`).join(", ") : "none: every file the ingests looked at went in";
      for (const r of s.refused) {
        const tr = el("tr");
        cell(tr, r.member ? `${r.path} › ${r.member}` : r.path);
        cell(tr, r.outcome);
        cell(tr, r.reason);
        cell(tr, r.logged_at);
        $("refused").tBodies[0].appendChild(tr);
      }
    }
    document.body.dataset.ready = "1";
  }

  main();
})();
