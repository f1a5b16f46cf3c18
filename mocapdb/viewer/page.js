// mocapdb viewer: the skeleton of one motion, animated, above its labels over time.
// Self-contained: no libraries, no network. The data are in <script id="mocapdb-data">
// (see mocapdb/viewer/encoding.py for the encoding). ?selftest=1 clicks every segment and
// reports in #selftest whether the animation went there, and drags a selection along the
// timeline. #frame=N opens the page at frame N (1-based, 30 Hz), #frame=A-B with frames A–B
// selected (the links of a `mocapdb similar --format html` results page).
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);

  // errors are written into the page by errors.js, inlined before this script

  const D = JSON.parse($("mocapdb-data").textContent);
  const N = D.n, FPS = D.fps, J = D.joints.length;

  // -- data -----------------------------------------------------------------------------------
  async function inflate(b64) {
    const text = atob(b64);
    const bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }

  // poses: second differences over time of root-relative integer steps, channel-major → absolute
  // positions (float32, frame-major: frame t, joint j, axis k at (t·J + j)·3 + k)
  async function decodePoses(rec) {
    const bytes = await inflate(rec.data);
    const q = rec.dtype === "int16" ? new Int16Array(bytes.buffer, 0, bytes.byteLength / 2)
                                    : new Int32Array(bytes.buffer, 0, bytes.byteLength / 4);
    const C = J * 3, steps = new Float64Array(N * C);
    for (let c = 0; c < C; c++) {
      let vel = 0, pos = 0;
      for (let t = 0, i = c * N; t < N; t++, i++) {
        vel += q[i];
        pos += vel;
        steps[t * C + c] = pos;
      }
    }
    const out = new Float32Array(N * C), u = rec.unit, o = rec.origin;
    for (let t = 0; t < N; t++) {
      const b = t * C;
      for (let j = 0; j < J; j++) {
        for (let k = 0; k < 3; k++) {
          out[b + j * 3 + k] = (j === 0 ? steps[b + k] : steps[b + k] + steps[b + j * 3 + k]) * u + o[k];
        }
      }
    }
    return out;
  }

  // -- the 3-D view: orbit camera, perspective projection, 2-D canvas ---------------------------
  const canvas = $("skeleton"), ctx = canvas.getContext("2d");
  const cam = { yaw: 0.7, pitch: 0.25, dist: 1, fov: 0.75 };
  let P = null, bodySize = 1, floorY = 0, defaultDist = 1, targets = null, reach = 1;
  const SIDE_COLOR = { l: "#1f77b4", r: "#d62728", c: "#333" };

  function fitCanvas() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  }

  function makeProjector(target) {
    const cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw), cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
    const W = canvas.width, H = canvas.height, f = (H / 2) / Math.tan(cam.fov / 2);
    return (x, y, z) => {
      const dx = x - target[0], dy = y - target[1], dz = z - target[2];
      const x1 = cy * dx - sy * dz, z1 = sy * dx + cy * dz;
      const y2 = cp * dy - sp * z1, z2 = sp * dy + cp * z1;
      const depth = cam.dist - z2;
      if (depth < cam.dist * 0.05) return null;
      return [W / 2 + (x1 * f) / depth, H / 2 - (y2 * f) / depth, depth];
    };
  }

  function joint(t, j) {
    const b = (t * J + j) * 3;
    return [P[b], P[b + 1], P[b + 2]];
  }

  function drawSkeleton(t) {
    fitCanvas();
    const W = canvas.width, H = canvas.height;
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, W, H);
    if (!P) return;
    const root = joint(t, 0);
    const target = [targets[t * 3], targets[t * 3 + 1], targets[t * 3 + 2]];
    const proj = makeProjector(target);
    // the floor: a grid around the root, half a body size per cell
    const cell = bodySize / 2, cx = Math.round(root[0] / cell) * cell, cz = Math.round(root[2] / cell) * cell;
    ctx.strokeStyle = "#e4e4e4";
    ctx.lineWidth = Math.max(1, H / 400);
    for (let i = -6; i <= 6; i++) {
      for (const [a, b] of [[[cx + i * cell, cz - 6 * cell], [cx + i * cell, cz + 6 * cell]],
                            [[cx - 6 * cell, cz + i * cell], [cx + 6 * cell, cz + i * cell]]]) {
        const p = proj(a[0], floorY, a[1]), q = proj(b[0], floorY, b[1]);
        if (p && q) { ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke(); }
      }
    }
    // shadow, then bones far to near, then joints
    const pts = [];
    for (let j = 0; j < J; j++) { const p = joint(t, j); pts.push(proj(p[0], p[1], p[2])); }
    ctx.strokeStyle = "rgba(0,0,0,0.12)";
    ctx.lineWidth = Math.max(2, H / 120);
    ctx.lineCap = "round";
    for (const [a, b] of D.bones) {
      const pa = joint(t, a), pb = joint(t, b);
      const p = proj(pa[0], floorY, pa[2]), q = proj(pb[0], floorY, pb[2]);
      if (p && q) { ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke(); }
    }
    const bones = D.bones.map(([a, b]) => [a, b, pts[a] && pts[b] ? (pts[a][2] + pts[b][2]) / 2 : -1]);
    bones.sort((x, y) => y[2] - x[2]);
    ctx.lineWidth = Math.max(2, H / 110);
    for (const [a, b, depth] of bones) {
      if (depth < 0) continue;
      ctx.strokeStyle = SIDE_COLOR[D.side[b]] || SIDE_COLOR.c;
      ctx.beginPath(); ctx.moveTo(pts[a][0], pts[a][1]); ctx.lineTo(pts[b][0], pts[b][1]); ctx.stroke();
    }
    ctx.fillStyle = "#111";
    for (const p of pts) {
      if (!p) continue;
      ctx.beginPath(); ctx.arc(p[0], p[1], Math.max(2, H / 160), 0, 2 * Math.PI); ctx.fill();
    }
    // where the figure landed, for a look from outside (a test that it stays inside the canvas)
    const xs = pts.filter((p) => p).map((p) => p[0]), ys = pts.filter((p) => p).map((p) => p[1]);
    canvas.dataset.figure = [Math.min(...xs), Math.min(...ys), Math.max(...xs), Math.max(...ys), W, H]
      .map((v) => v.toFixed(1)).join(",");
  }

  // The camera's framing from the body's actual extent over the whole take, whatever the root does (fixed,
  // or far up and down as in a dance or a rope swing): it looks at the centre of each frame's joints,
  // smoothed over half a second so it glides, and starts far enough away that the farthest joint from that
  // point over the take stays inside the canvas from any side.
  function framing() {
    const centre = new Float64Array(N * 3);
    for (let t = 0; t < N; t++) {
      for (let k = 0; k < 3; k++) {
        let lo = Infinity, hi = -Infinity;
        for (let j = 0; j < J; j++) { const v = P[(t * J + j) * 3 + k]; lo = Math.min(lo, v); hi = Math.max(hi, v); }
        centre[t * 3 + k] = (lo + hi) / 2;
      }
    }
    // a moving average over half a second (prefix sums: linear in the frames)
    const half = Math.max(1, Math.round(FPS / 4)), sums = new Float64Array((N + 1) * 3);
    for (let t = 0; t < N; t++) for (let k = 0; k < 3; k++) sums[(t + 1) * 3 + k] = sums[t * 3 + k] + centre[t * 3 + k];
    targets = new Float64Array(N * 3);
    let far = 0;
    for (let t = 0; t < N; t++) {
      const a = Math.max(0, t - half), b = Math.min(N, t + half + 1);
      for (let k = 0; k < 3; k++) targets[t * 3 + k] = (sums[b * 3 + k] - sums[a * 3 + k]) / (b - a);
      for (let j = 0; j < J; j++) {
        const q = (t * J + j) * 3;
        const dx = P[q] - targets[t * 3], dy = P[q + 1] - targets[t * 3 + 1], dz = P[q + 2] - targets[t * 3 + 2];
        far = Math.max(far, dx * dx + dy * dy + dz * dz);
      }
    }
    reach = Math.max(Math.sqrt(far), 1e-6);
  }

  // the distance at which a sphere of radius `reach` around the target fills at most 90 % of the canvas's
  // shorter side: a point of it is at least dist - reach deep and at most reach off the axis
  function fittingDistance() {
    fitCanvas();
    const W = canvas.width, H = canvas.height, f = (H / 2) / Math.tan(cam.fov / 2);
    return reach + (reach * f) / (0.45 * Math.min(W, H));
  }

  // -- player -------------------------------------------------------------------------------------
  const player = { frame: 0, playing: false, speed: 1, last: 0 };
  const scrubber = $("scrubber"), playButton = $("play"), clock = $("clock"), hud = $("hud");
  let playhead = null;

  function activeLabels(f) {
    const on = [];
    for (const s of D.segments) if (s.start - 1 <= f && f <= s.end - 1) on.push(s.label);
    return on;
  }

  function render() {
    const f = Math.round(player.frame);
    drawSkeleton(f);
    scrubber.value = String(f);
    clock.textContent = `${(f / FPS).toFixed(2)} s · frame ${f + 1}/${N}`;
    hud.textContent = activeLabels(f).join(", ");
    if (playhead) playhead.style.left = `calc(var(--name-w) + (100% - var(--name-w)) * ${(f + 0.5) / N})`;
  }

  function seek(frame) {
    player.frame = Math.min(N - 1, Math.max(0, frame));
    render();
  }

  function setPlaying(on) {
    player.playing = on;
    playButton.textContent = on ? "pause" : "play";
    if (on) {
      if (player.frame >= N - 1) player.frame = 0;
      player.last = performance.now();
      requestAnimationFrame(tick);
    }
  }

  function tick(now) {
    if (!player.playing) return;
    const dt = Math.max(0, (now - player.last) / 1000);
    player.last = now;
    player.frame += dt * FPS * player.speed;
    if (player.frame >= N - 1) { player.frame = N - 1; setPlaying(false); }
    render();
    if (player.playing) requestAnimationFrame(tick);
  }

  // the model's τ in the header: one value, or the range of the classes' (a list of every class's τ
  // read as a row of tick labels)
  function tauText(taus) {
    return taus.length === 1 ? `τ ${taus[0]}` : `τ ${taus[0]}–${taus[taus.length - 1]} (per class)`;
  }

  // -- timeline: lanes of segments, the Δ̄ heat map, an axis, the playhead ------------------------
  function el(tag, cls, text) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    return e;
  }

  function frameAt(track, clientX) {
    const r = track.getBoundingClientRect();
    return Math.min(N - 1, Math.max(0, Math.floor(((clientX - r.left) / r.width) * N)));
  }

  function trackRow(name, extraClass) {
    const row = el("div", "row" + (extraClass ? " " + extraClass : ""));
    row.appendChild(el("div", "rowname", name)).title = name;
    const track = el("div", "track");
    track.addEventListener("click", (e) => {
      if (dragged) { dragged = false; return; }  // the end of a selection, not a click
      seek(frameAt(track, e.clientX));
    });
    // dragging along a track selects a stretch (frames, 0-based inclusive)
    track.addEventListener("pointerdown", (e) => {
      selecting = { track, from: frameAt(track, e.clientX), x: e.clientX };
    });
    row.appendChild(track);
    return [row, track];
  }

  // -- selection: a stretch of the timeline, offered as a `mocapdb similar` command ---------------
  let selecting = null, dragged = false, selectionBox = null;
  const selection = { first: -1, last: -1 };

  function shellWord(s) {
    return /^[A-Za-z0-9_.:+\/-]+$/.test(s) ? s : `'${s.replace(/'/g, "'\\''")}'`;
  }

  function similarCommand(first, last) {
    return `mocapdb similar ${shellWord(D.name)} --start-frame ${first + 1} --end-frame ${last + 1}`;
  }

  function select(first, last) {
    selection.first = Math.min(N - 1, Math.max(0, Math.min(first, last)));
    selection.last = Math.min(N - 1, Math.max(0, Math.max(first, last)));
    const box = $("similar");
    box.hidden = false;
    $("similar-range").textContent = `${selection.first + 1}–${selection.last + 1} ` +
      `(${(selection.first / FPS).toFixed(2)}–${((selection.last + 1) / FPS).toFixed(2)} s)`;
    const cmd = similarCommand(selection.first, selection.last);
    $("similar-command").textContent = cmd;
    box.dataset.first = String(selection.first + 1);
    box.dataset.last = String(selection.last + 1);
    if (selectionBox) {
      selectionBox.hidden = false;
      selectionBox.style.left = `calc(var(--name-w) + (100% - var(--name-w)) * ${selection.first / N})`;
      selectionBox.style.width = `calc((100% - var(--name-w)) * ${(selection.last - selection.first + 1) / N})`;
    }
    $("copy-similar").textContent = "copy";
  }

  async function copyCommand() {
    const text = $("similar-command").textContent, button = $("copy-similar");
    try {
      await navigator.clipboard.writeText(text);
    } catch (err) {  // no clipboard API (an insecure context): copy the selected text instead
      const range = document.createRange();
      range.selectNodeContents($("similar-command"));
      const sel = window.getSelection();
      sel.removeAllRanges();
      sel.addRange(range);
      document.execCommand("copy");
    }
    button.textContent = "copied";
  }

  function bindSelection() {
    window.addEventListener("pointermove", (e) => {
      if (!selecting) return;
      if (!dragged && Math.abs(e.clientX - selecting.x) < 4) return;
      dragged = true;
      select(selecting.from, frameAt(selecting.track, e.clientX));
    });
    window.addEventListener("pointerup", () => {
      if (selecting && dragged) seek(selection.first);
      selecting = null;
    });
    $("copy-similar").addEventListener("click", copyCommand);
  }

  // #frame=N or #frame=A-B (1-based)
  function applyFragment() {
    const m = /^#frame=(\d+)(?:-(\d+))?$/.exec(location.hash);
    if (!m) return false;
    const a = Number(m[1]) - 1, b = m[2] === undefined ? a : Number(m[2]) - 1;
    if (m[2] !== undefined) select(a, b);
    seek(Math.min(a, b));
    return true;
  }

  function segmentLane(title, lane, segs, rowLabels) {
    const box = el("div", "lane");
    box.dataset.lane = lane;
    box.appendChild(el("div", "lane-title", title));
    const tracks = {};
    for (const lab of rowLabels) {
      const [row, track] = trackRow(lab);
      tracks[lab] = track;
      box.appendChild(row);
    }
    for (const s of segs) {
      const e = el("div", "seg" + (lane === "truth" ? " truth" : ""));
      e.dataset.label = s.label;
      e.dataset.lane = lane;
      e.dataset.start = String(s.start);
      e.dataset.end = String(s.end);
      e.style.left = `${((s.start - 1) / N) * 100}%`;
      e.style.width = `${((s.end - s.start + 1) / N) * 100}%`;
      e.style.background = D.colors[s.label] || "#888";
      e.title = `${s.label}: ${((s.start - 1) / FPS).toFixed(2)}–${(s.end / FPS).toFixed(2)} s` +
                (s.cost !== undefined ? `, cost ${s.cost}` : "");
      e.addEventListener("click", (ev) => { ev.stopPropagation(); seek(s.start - 1); });
      tracks[s.label].appendChild(e);
    }
    return box;
  }

  // Δ̄ bytes → colours: 0 (a perfect match) dark blue … 254 (τ) red, 255 (above τ) white (paper Fig. 3)
  function heatColor(v) {
    if (v === 255) return [255, 255, 255];
    const x = v / 254, r = Math.min(1, Math.max(0, 1.5 - Math.abs(4 * x - 3))),
          g = Math.min(1, Math.max(0, 1.5 - Math.abs(4 * x - 2))), b = Math.min(1, Math.max(0, 1.5 - Math.abs(4 * x - 1)));
    return [Math.round(255 * r), Math.round(255 * g), Math.round(255 * b)];
  }

  function heatLane(bytes) {
    const box = el("div", "lane");
    box.dataset.lane = "delta";
    box.appendChild(el("div", "lane-title", `Δ̄ per label (blue: close match … red: τ; white: above τ)`));
    const bins = Math.min(N, 4096), per = N / bins;
    D.labels.forEach((lab, row) => {
      const [r, track] = trackRow(lab, "heat");
      const c = document.createElement("canvas");
      c.width = bins; c.height = 1;
      c.dataset.label = lab;
      const g = c.getContext("2d"), img = g.createImageData(bins, 1);
      for (let b = 0; b < bins; b++) {
        let v = 255;  // the best (smallest) Δ̄ of the frames a pixel covers
        for (let t = Math.floor(b * per), end = Math.max(t + 1, Math.floor((b + 1) * per)); t < end && t < N; t++) {
          v = Math.min(v, bytes[row * N + t]);
        }
        const [R, G, B] = heatColor(v);
        img.data.set([R, G, B, 255], b * 4);
      }
      g.putImageData(img, 0, 0);
      track.appendChild(c);
      box.appendChild(r);
    });
    return box;
  }

  function axis() {
    const a = el("div", "axis"), seconds = N / FPS;
    const step = [1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 1800].find((s) => seconds / s <= 12) || 3600;
    for (let s = 0; s <= seconds; s += step) {
      const t = el("span", null, s >= 60 ? `${Math.floor(s / 60)}:${String(Math.round(s % 60)).padStart(2, "0")}` : `${s}s`);
      t.style.left = `${(s / seconds) * 100}%`;
      a.appendChild(t);
    }
    return a;
  }

  function buildTimeline(deltaBytes) {
    const tl = $("timeline");
    tl.appendChild(segmentLane(`annotation (model ${D.model})`, "annotation", D.segments, D.labels));
    if (D.truth) {
      const truthLabels = [...new Set(D.truth.map((s) => s.label))];
      tl.appendChild(segmentLane("ground truth", "truth", D.truth, truthLabels));
    }
    tl.appendChild(heatLane(deltaBytes));
    tl.appendChild(axis());
    playhead = el("div");
    playhead.id = "playhead";
    tl.appendChild(playhead);
    selectionBox = el("div");
    selectionBox.id = "selection";
    selectionBox.hidden = true;
    tl.appendChild(selectionBox);
  }

  // -- interaction -------------------------------------------------------------------------------
  function bindControls() {
    scrubber.max = String(N - 1);
    scrubber.addEventListener("input", () => seek(Number(scrubber.value)));
    playButton.addEventListener("click", () => setPlaying(!player.playing));
    $("speed").addEventListener("change", (e) => { player.speed = Number(e.target.value); });
    document.addEventListener("keydown", (e) => {
      if (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") return;
      if (e.key === " ") { e.preventDefault(); setPlaying(!player.playing); }
      else if (e.key === "ArrowRight") seek(Math.round(player.frame) + 1);
      else if (e.key === "ArrowLeft") seek(Math.round(player.frame) - 1);
    });
    let drag = null;
    canvas.addEventListener("pointerdown", (e) => {
      drag = [e.clientX, e.clientY];
      canvas.classList.add("dragging");
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener("pointermove", (e) => {
      if (!drag) return;
      cam.yaw += (e.clientX - drag[0]) * 0.01;
      cam.pitch = Math.min(1.45, Math.max(-1.45, cam.pitch + (e.clientY - drag[1]) * 0.01));
      drag = [e.clientX, e.clientY];
      render();
    });
    const stop = () => { drag = null; canvas.classList.remove("dragging"); };
    canvas.addEventListener("pointerup", stop);
    canvas.addEventListener("pointercancel", stop);
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      cam.dist = Math.min(defaultDist * 20, Math.max(defaultDist * 0.15, cam.dist * Math.exp(e.deltaY * 0.001)));
      render();
    }, { passive: false });
    canvas.addEventListener("dblclick", () => { cam.yaw = 0.7; cam.pitch = 0.25; cam.dist = defaultDist; render(); });
    window.addEventListener("resize", render);
  }

  // -- self test (?selftest=1): every segment click must seek to the segment's first frame --------
  function selfTest() {
    const out = $("selftest"), failures = [];
    const segs = document.querySelectorAll(".seg");
    for (const e of segs) {
      e.click();
      const want = Number(e.dataset.start) - 1;
      if (Math.round(player.frame) !== want || Number(scrubber.value) !== want) {
        failures.push(`${e.dataset.lane}/${e.dataset.label}@${e.dataset.start}: at frame ${player.frame}`);
      }
    }
    const px = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
    let ink = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i] < 200 || px[i + 1] < 200 || px[i + 2] < 200) ink++;
    if (ink === 0) failures.push("the skeleton canvas is blank");
    const heat = document.querySelectorAll(".heat canvas").length;
    if (heat !== D.labels.length) failures.push(`${heat} heat-map rows for ${D.labels.length} labels`);
    // a drag along the first track from 20 % to 40 % of its width selects those frames
    const track = document.querySelector(".track"), r = track.getBoundingClientRect();
    const at = (f) => r.left + r.width * f, y = r.top + r.height / 2;
    const from = frameAt(track, at(0.2)), to = frameAt(track, at(0.4));
    track.dispatchEvent(new PointerEvent("pointerdown", { clientX: at(0.2), clientY: y, bubbles: true }));
    window.dispatchEvent(new PointerEvent("pointermove", { clientX: at(0.3), clientY: y, bubbles: true }));
    window.dispatchEvent(new PointerEvent("pointermove", { clientX: at(0.4), clientY: y, bubbles: true }));
    window.dispatchEvent(new PointerEvent("pointerup", { clientX: at(0.4), clientY: y, bubbles: true }));
    track.dispatchEvent(new MouseEvent("click", { clientX: at(0.4), clientY: y, bubbles: true }));
    const command = $("similar-command").textContent;
    if (command !== similarCommand(from, to)) failures.push(`dragging selected "${command}"`);
    if (Math.round(player.frame) !== from) failures.push(`after the selection at frame ${player.frame}, not ${from}`);
    out.dataset.command = command;
    out.dataset.selection = `${from + 1}-${to + 1}`;
    seek(0);
    // decoded poses at a few frames and joints, for the test to compare with the source
    const probes = [];
    for (const t of [0, Math.floor(N / 2), N - 1]) for (const j of [0, 3, 12, 22]) probes.push([t, j, ...joint(t, j)]);
    out.hidden = false;
    out.dataset.status = failures.length ? "fail" : "pass";
    out.dataset.segments = String(segs.length);
    out.dataset.ink = String(ink);
    out.dataset.poses = JSON.stringify(probes);
    out.textContent = failures.length ? `FAIL\n${failures.join("\n")}` : `PASS ${segs.length} segments`;
  }

  async function main() {
    const [poses, deltaBytes] = await Promise.all([decodePoses(D.pose), inflate(D.delta.data)]);
    P = poses;
    // body size (the floor grid's cells) from the first pose, the floor from all of them
    let size = 0;
    for (let k = 0; k < 3; k++) {
      let lo = Infinity, hi = -Infinity;
      for (let j = 0; j < J; j++) { lo = Math.min(lo, P[j * 3 + k]); hi = Math.max(hi, P[j * 3 + k]); }
      size = Math.max(size, hi - lo);
    }
    let floor = Infinity;
    for (let i = 1; i < P.length; i += 3) floor = Math.min(floor, P[i]);
    bodySize = Math.max(size, 1e-6);
    floorY = floor;
    framing();
    cam.dist = defaultDist = fittingDistance();
    const secs = N / FPS;
    $("meta").textContent = `${D.n} frames at ${FPS} Hz (${secs.toFixed(1)} s; source ${D.sourceFps} Hz: ${D.source}) · ` +
      `model ${D.model}, ${tauText(D.tau)}, keyframes ${D.keyframes ? "on" : "off"} · ${D.segments.length} segments`;
    if (D.index) {
      const a = el("a", null, "← all motions");
      a.href = D.index;
      $("meta").prepend(a, " · ");
    }
    buildTimeline(deltaBytes);
    bindControls();
    bindSelection();
    render();
    if (applyFragment()) {
      document.body.dataset.openedAt = String(Math.round(player.frame) + 1);
    }
    window.addEventListener("hashchange", applyFragment);
    document.body.dataset.ready = "1";
    document.body.dataset.loadMs = performance.now().toFixed(1);
    if (new URLSearchParams(location.search).has("selftest")) selfTest();
  }

  main();
})();
