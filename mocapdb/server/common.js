// mocapdb serve, shared by its pages: JSON from /api/ (a busy database is said and asked again), elements.
// (Errors go into #errors through the viewer's errors.js, inlined once per page before this.)
"use strict";
const serve = (function () {
  const $ = (id) => document.getElementById(id);

  // GET a JSON answer; while another process writes the database (HTTP 503) say so and ask again
  async function api(url) {
    for (;;) {
      const r = await fetch(url, { headers: { Accept: "application/json" } });
      const body = await r.json();
      const busy = $("busy");
      if (r.status === 503) {
        busy.hidden = false;
        busy.textContent = `${body.message} — asking again in a moment…`;
        document.body.dataset.busy = "1";
        await new Promise((ok) => setTimeout(ok, 2000));
        continue;
      }
      busy.hidden = true;
      if (!r.ok) throw new Error(body.message || `${url}: HTTP ${r.status}`);
      return body;
    }
  }

  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined && text !== null) e.textContent = String(text);
    return e;
  }

  function cell(tr, text, cls) {
    const td = el("td", cls, text);
    tr.appendChild(td);
    return td;
  }

  function link(href, text) {
    const a = el("a", null, text);
    a.href = href;
    return a;
  }

  function duration(s) {
    if (s < 59.95) return `${s.toFixed(1)} s`;
    const whole = Math.round(s), m = Math.floor(whole / 60), h = Math.floor(m / 60);
    return h ? `${h} h ${String(m % 60).padStart(2, "0")} min` : `${m} min ${String(whole % 60).padStart(2, "0")} s`;
  }

  // a motion's label strip: runs [label, first, last, row] of `bins` cells along its duration; concurrent
  // labels (a turn during a move) on rows of their own, so none hides another
  function strip(runs, bins, colors, rows) {
    const box = el("div", "strip"), n = Math.max(1, rows || 1);
    box.style.height = `${Math.max(12, 7 * n)}px`;
    box.dataset.rows = String(n);
    for (const [label, a, b, row] of runs) {
      const s = el("span");
      s.dataset.label = label;
      s.dataset.row = String(row || 0);
      s.style.left = `${(a / bins) * 100}%`;
      s.style.width = `${((b - a + 1) / bins) * 100}%`;
      s.style.top = `${((row || 0) / n) * 100}%`;
      s.style.height = `${100 / n}%`;
      s.style.background = colors[label] || "#888";
      s.title = label;
      box.appendChild(s);
    }
    return box;
  }

  function chip(label, colors) {
    const c = el("span", "chip", label);
    c.style.background = colors[label] || "#888";
    return c;
  }

  return { $, api, el, cell, link, duration, strip, chip };
})();
