// mocapdb serve, the archive page: every motion with its folder, format, rate, duration, labels and label strip;
// filters, sort and pages through /api/motions. The filters live in the address (?label=…&q=…), so a
// filtered view is a link. When the rows are shown, <body data-ready> holds the request it answers.
(function () {
  const { $, api, el, cell, link, duration, strip, chip } = serve;
  const form = $("filters"), FIELDS = ["q", "label", "source_format", "min_s", "max_s", "sort", "limit"];
  let offset = 0, total = 0, colors = {}, shown = 0, ticket = 0;

  function params() {
    const p = new URLSearchParams();
    for (const f of FIELDS) {
      const v = form.elements[f].value.trim();
      if (v !== "" && !(f === "sort" && v === "id") && !(f === "limit" && v === "50")) p.set(f, v);
    }
    if (offset) p.set("offset", String(offset));
    return p;
  }

  async function load() {
    const p = params(), mine = ++ticket;
    history.replaceState(null, "", p.toString() ? `?${p}` : location.pathname);
    const page = await api(`/api/motions?${p}`);
    if (mine !== ticket) return;  // a newer request is on its way
    colors = page.colors;
    total = page.total;
    const body = $("motions").tBodies[0];
    body.replaceChildren();
    for (const m of page.rows) {
      const tr = el("tr");
      tr.dataset.motion = String(m.motion_id);
      tr.dataset.name = m.name;
      cell(tr, null).appendChild(link(`/motion/${m.motion_id}`, m.name));
      // the folder's last parts tell sessions apart; the whole path on hover
      const parts = (m.folder || "").split(/[\\/]/).filter((x) => x);
      const folder = cell(tr, parts.length > 2 ? `…/${parts.slice(-2).join("/")}` : m.folder, "folder");
      folder.title = m.source_path;
      cell(tr, m.format);
      cell(tr, Number(m.source_fps).toFixed(0), "num");
      cell(tr, duration(m.seconds), "num").dataset.seconds = String(m.seconds);
      const labs = cell(tr, null);
      for (const lab of m.labels) labs.appendChild(chip(lab, colors));
      cell(tr, null, "strip").appendChild(strip(m.strip, page.strip_bins, colors, m.strip_rows));
      body.appendChild(tr);
    }
    shown = page.rows.length;
    const limit = page.limit;
    $("count").textContent = total ? `${total} motion(s)${p.has("q") || p.has("label") || p.has("source_format") ||
      p.has("min_s") || p.has("max_s") ? " match" : ""}; showing ${offset + 1}–${offset + shown}` : "no motion matches";
    $("page").textContent = total ? `page ${Math.floor(offset / limit) + 1} of ${Math.max(1, Math.ceil(total / limit))}` : "";
    $("prev").disabled = offset === 0;
    $("next").disabled = offset + shown >= total;
    document.body.dataset.ready = p.toString() || "all";
    document.body.dataset.total = String(total);
  }

  async function facets() {
    const s = await api("/api/stats");
    $("meta").textContent += ` · ${s.motions} motion(s), ${s.hours.toFixed(2)} h · labels of model ${s.model}`;
    const fill = (select, values) => {
      for (const v of values) if (![...select.options].some((o) => o.value === v)) select.appendChild(new Option(v, v));
    };
    fill(form.elements.label, s.labels.map((r) => r.label));
    fill(form.elements.source_format, [...new Set(s.formats.map((r) => r.format))]);
  }

  async function main() {
    const q = new URLSearchParams(location.search);
    for (const f of FIELDS) {
      if (!q.has(f)) continue;
      const input = form.elements[f];
      if (input.tagName === "SELECT" && ![...input.options].some((o) => o.value === q.get(f))) {
        input.appendChild(new Option(q.get(f), q.get(f)));
      }
      input.value = q.get(f);
    }
    offset = Math.max(0, Number(q.get("offset")) || 0);
    let timer = null;
    form.addEventListener("input", () => {
      clearTimeout(timer);
      timer = setTimeout(() => { offset = 0; load(); }, 250);
    });
    form.addEventListener("submit", (e) => e.preventDefault());
    $("prev").addEventListener("click", () => { offset = Math.max(0, offset - Number(form.elements.limit.value)); load(); });
    $("next").addEventListener("click", () => { offset += Number(form.elements.limit.value); load(); });
    // the rows and the filters' choices are asked for at once: the first rows wait for one answer only
    await Promise.all([load(), facets()]);
  }

  main();
})();
