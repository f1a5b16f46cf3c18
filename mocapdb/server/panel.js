// mocapdb serve, under a motion's viewer: "find similar" ranks the stretches of the archive most like the
// selected stretch (or the whole motion) through /api/similar, each linked to its motion's page at the hit;
// "all segments labelled …" lists a label's stored segments across the archive (/api/segments).
// ?find=1 runs the search once the viewer is ready (with #frame=A-B: on frames A–B); ?play=1 starts playing.
(function () {
  const { $, api, el, cell, link } = serve;
  const S = JSON.parse($("serve-data").textContent);
  const opts = new URLSearchParams(location.search);
  let labelOffset = 0;

  function stretch() {
    const box = $("similar");  // the viewer's selection box: data-first/data-last once a stretch is selected
    if (box && !box.hidden && box.dataset.first) return [Number(box.dataset.first), Number(box.dataset.last)];
    return [1, S.n];
  }

  function frames(a, b) {
    return `${a}–${b}`;
  }

  async function find() {
    const [a, b] = stretch(), limit = $("find-limit").value, features = $("find-features").value;
    const button = $("find-similar"), status = $("find-status");
    button.disabled = true;
    status.textContent = `searching the archive for frames ${frames(a, b)}…`;
    const t0 = performance.now();
    try {
      const r = await api(`/api/similar?motion=${S.motion_id}&start_frame=${a}&end_frame=${b}&limit=${limit}` +
                          `&features=${encodeURIComponent(features)}`);
      const body = $("similar-results").tBodies[0];
      body.replaceChildren();
      r.rows.forEach((h, k) => {
        const tr = el("tr", "hit");
        tr.dataset.motion = String(h.motion_id);
        tr.dataset.start = String(h.start_frame);
        tr.dataset.end = String(h.end_frame);
        cell(tr, k + 1, "num");
        cell(tr, null).appendChild(link(`/motion/${h.motion_id}#frame=${h.start_frame}-${h.end_frame}`, h.document));
        cell(tr, frames(h.start_frame, h.end_frame), "num");
        cell(tr, `${h.start_s.toFixed(2)}–${h.end_s.toFixed(2)}`, "num");
        cell(tr, h.cost.toFixed(4), "num");
        body.appendChild(tr);
      });
      $("similar-results").hidden = r.rows.length === 0;
      status.textContent = `${r.rows.length} stretch(es) most like frames ${frames(a, b)}, cheapest first ` +
        `(cost: the weighted Δ; ${((performance.now() - t0) / 1000).toFixed(2)} s)`;
      status.dataset.query = `${a}-${b}`;
      document.body.dataset.similar = String(r.rows.length);
    } catch (err) {
      status.textContent = `find similar: ${err.message}`;
      document.body.dataset.similar = "error";
    } finally {
      button.disabled = false;
    }
  }

  async function labelSegments(more) {
    const label = $("label-pick").value, body = $("label-results").tBodies[0];
    if (!more) { labelOffset = 0; body.replaceChildren(); }
    if (!label) return;
    const r = await api(`/api/segments?label=${encodeURIComponent(label)}&limit=25&offset=${labelOffset}`);
    for (const s of r.rows) {
      const tr = el("tr");
      tr.dataset.motion = String(s.motion_id);
      cell(tr, null).appendChild(link(`/motion/${s.motion_id}#frame=${s.start_frame}-${s.end_frame}`, s.name));
      cell(tr, frames(s.start_frame, s.end_frame), "num");
      cell(tr, `${s.start_s.toFixed(2)}–${s.end_s.toFixed(2)}`, "num");
      cell(tr, s.cost.toFixed(4), "num");
      body.appendChild(tr);
    }
    labelOffset += r.rows.length;
    $("label-results").hidden = labelOffset === 0;
    $("label-more").hidden = labelOffset >= r.total;
    $("label-status").textContent = `${r.total} segment(s) labelled ${label} (model ${S.model}), longest first; ` +
      `showing ${labelOffset}`;
  }

  function whenViewerReady(fn) {
    if (document.body.dataset.ready === "1") fn();
    else setTimeout(() => whenViewerReady(fn), 50);
  }

  const pick = $("label-pick");
  pick.appendChild(new Option("(choose a label)", ""));
  const own = new Set(S.labels);
  for (const lab of [...S.labels, ...S.all_labels.filter((x) => !own.has(x))]) pick.appendChild(new Option(lab, lab));
  pick.addEventListener("change", () => labelSegments(false));
  $("label-more").addEventListener("click", () => labelSegments(true));
  $("find-similar").addEventListener("click", find);
  whenViewerReady(() => {
    if (opts.has("find")) find();
    if (opts.has("play")) $("play").click();
  });
})();
