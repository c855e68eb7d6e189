// pushtrain report: the map with the train at the chosen time, the time series with a cursor,
// the summary. Plain JavaScript, no dependencies; the data is the JSON in #report-data
// (written by pushtrain.report.html). Units: metres, seconds, radians unless a panel says so.
"use strict";
(function () {
  const D = JSON.parse(document.getElementById("report-data").textContent);
  const COLORS = {robot: "#d62728", trailer: "#1f77b4", path: "#2ca02c", ref: "#111111",
                  robotTrace: "#d62728", lastTrace: "#1f77b4", keepOut: "#ff7f0e",
                  tree: "#8c8c8c", partial: "#1f77b4", route: "#2ca02c", bottleneck: "#dc143c",
                  wideEnough: "#737373"};
  // the widest way's narrowest passage where it is wide enough: drawn grey (not the cause)
  const wideEnough = (b) => (b.what || "bottleneck") === "bottleneck" && b.needed !== null &&
    b.width >= b.needed;
  const LINE_COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
                       "#17becf", "#bcbd22", "#7f7f7f"];
  const isRun = D.kind === "run";
  const $ = (id) => document.getElementById(id);
  $("title").textContent = D.title;
  $("message").textContent = D.message || (D.summary && D.summary.message) || "";
  (D.notes || []).forEach((text) => {  // what is not drawn (values not finite, no rows)
    const p = document.createElement("p"); p.className = "note"; p.textContent = text;
    $("message").after(p);
  });
  const hasRows = isRun && D.t.length > 0;
  function range(values) {  // [min, max] of the non-null values (no spread: long arrays)
    let lo = Infinity, hi = -Infinity;
    for (const v of values) { if (v !== null) { if (v < lo) lo = v; if (v > hi) hi = v; } }
    return [lo, hi];
  }

  // ---------------------------------------------------------------- map view
  const canvas = $("map");
  const ctx = canvas.getContext("2d");
  const layer = document.createElement("canvas");  // everything but the train, per view
  const lctx = layer.getContext("2d");
  let dpr = window.devicePixelRatio || 1;
  const view = {x0: 0, y1: 0, s: 1};  // world x at the left edge, y at the top, px per metre
  let mapImage = null;
  let drawnBodies = [];   // the corners drawn last, in canvas pixels (read back by the tests)
  let drawnBottleneck = null;

  function toPx(x, y) { return [(x - view.x0) * view.s, (view.y1 - y) * view.s]; }
  function toWorld(px, py) { return [px / view.s + view.x0, view.y1 - py / view.s]; }

  function worldExtent() {
    if (D.map) return D.map.extent.slice();
    let xs = [], ys = [];
    if (isRun) D.bodies.forEach((b) => { xs = xs.concat(b.x); ys = ys.concat(b.y); });
    else (D.tree || []).forEach((tr) => { xs = xs.concat(tr[0]); ys = ys.concat(tr[1]); });
    const [x0, x1] = range(xs), [y0, y1] = range(ys);
    if (!(x0 <= x1 && y0 <= y1)) return [-1, 1, -1, 1];
    const pad = 1.0;
    return [x0 - pad, x1 + pad, y0 - pad, y1 + pad];
  }

  function fit() {
    const e = worldExtent();
    const w = canvas.width, h = canvas.height;
    view.s = Math.min(w / (e[1] - e[0]), h / (e[3] - e[2]));
    view.x0 = 0.5 * (e[0] + e[1]) - 0.5 * w / view.s;
    view.y1 = 0.5 * (e[2] + e[3]) + 0.5 * h / view.s;
  }

  function resize() {
    dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr));
    const h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    const first = canvas.width !== w || canvas.height !== h;
    canvas.width = w; canvas.height = h; layer.width = w; layer.height = h;
    if (first) fit();
    redrawLayer();
    plots.forEach((p) => { p.resize(); p.draw(row); });
    draw();
  }

  function polyline(c, xs, ys, style) {
    c.save();
    c.strokeStyle = style.color; c.lineWidth = (style.width || 1) * dpr;
    c.globalAlpha = style.alpha === undefined ? 1 : style.alpha;
    if (style.dash) c.setLineDash(style.dash.map((v) => v * dpr));
    c.lineJoin = "round"; c.lineCap = "round";
    c.beginPath();
    let pen = false;
    for (let k = 0; k < xs.length; k++) {
      if (xs[k] === null || ys[k] === null) { pen = false; continue; }
      const p = toPx(xs[k], ys[k]);
      if (pen) c.lineTo(p[0], p[1]); else c.moveTo(p[0], p[1]);
      pen = true;
    }
    if (style.close) c.closePath();
    c.stroke();
    c.restore();
  }

  function marker(c, x, y, kind, color, size) {
    const p = toPx(x, y), r = size * dpr;
    c.save(); c.strokeStyle = color; c.fillStyle = color; c.lineWidth = 1.5 * dpr;
    c.beginPath();
    if (kind === "circle") { c.arc(p[0], p[1], r, 0, 2 * Math.PI); c.stroke(); }
    else { c.moveTo(p[0] - r, p[1] - r); c.lineTo(p[0] + r, p[1] + r);
           c.moveTo(p[0] - r, p[1] + r); c.lineTo(p[0] + r, p[1] - r); c.stroke(); }
    c.restore();
  }

  function redrawLayer() {
    const c = lctx;
    c.setTransform(1, 0, 0, 1, 0, 0);
    c.fillStyle = "#b8b8b8"; c.fillRect(0, 0, layer.width, layer.height);
    if (mapImage && mapImage.complete) {
      const e = D.map.extent;
      const a = toPx(e[0], e[3]), b = toPx(e[1], e[2]);
      c.imageSmoothingEnabled = view.s * (e[1] - e[0]) < mapImage.width;
      c.drawImage(mapImage, a[0], a[1], b[0] - a[0], b[1] - a[1]);
    }
    if (D.keep_out) D.keep_out.rings.forEach((r) =>
      polyline(c, r[0], r[1], {color: COLORS.keepOut, width: 1, dash: [4, 3]}));
    if (isRun) {
      if (D.path) polyline(c, D.path[0], D.path[1],
                           {color: COLORS.path, width: 7, alpha: 0.35});
      polyline(c, D.bodies[0].x, D.bodies[0].y, {color: COLORS.robotTrace, width: 1.2});
      const last = D.bodies[D.n];
      polyline(c, last.x, last.y, {color: COLORS.lastTrace, width: 1.2});
      if (D.reference) polyline(c, D.reference.x, D.reference.y,
                                {color: COLORS.ref, width: 1, dash: [5, 4]});
    } else {
      (D.tree || []).forEach((tr) => polyline(c, tr[0], tr[1],
                                              {color: COLORS.tree, width: 0.7}));
      if (D.route) polyline(c, D.route[0], D.route[1],
                            {color: COLORS.route, width: 5, alpha: 0.45});
      if (D.partial) polyline(c, D.partial[0], D.partial[1],
                              {color: COLORS.partial, width: 2.5});
      (D.failure_points || []).forEach((p) => marker(c, p.x, p.y, "x", "#e00000", 3));
      [["start", D.start, "#2ca02c"], ["goal", D.goal, "#d62728"]].forEach(([, pose, col]) => {
        if (!pose) return;
        const fp = D.footprints.trailer;
        const corners = rect(pose[0], pose[1], pose[2], fp[0], fp[1]);
        c.save(); c.fillStyle = col; c.globalAlpha = 0.35; fillPoly(c, corners); c.restore();
      });
      drawnBottleneck = null;
      if (D.bottleneck) {
        const b = D.bottleneck;
        const r = Math.max(10, 0.5 * (b.width || 1) * view.s / dpr);
        const col = wideEnough(b) ? COLORS.wideEnough : COLORS.bottleneck;
        marker(c, b.x, b.y, "circle", col, r);
        marker(c, b.x, b.y, "circle", col, r + 3);
        drawnBottleneck = toWorld(...toPx(b.x, b.y));
      }
    }
  }

  function rect(x, y, th, length, width) {
    const c = Math.cos(th), s = Math.sin(th);
    return [[1, 1], [-1, 1], [-1, -1], [1, -1]].map(([a, b]) => [
      x + 0.5 * length * a * c - 0.5 * width * b * s,
      y + 0.5 * length * a * s + 0.5 * width * b * c]);
  }

  function fillPoly(c, corners) {
    c.beginPath();
    corners.forEach((q, k) => { const p = toPx(q[0], q[1]); if (k) c.lineTo(p[0], p[1]);
                                else c.moveTo(p[0], p[1]); });
    c.closePath(); c.fill(); c.globalAlpha = 1; c.stroke();
  }

  function poseAt(i) {  // [[x, y, theta] of bodies 0..n] at view row i (or the failure's train)
    if (isRun) return hasRows ? D.bodies.map((b) => [b.x[i], b.y[i], b.theta[i]]) : [];
    if (!D.train) return [];
    return D.train.x.map((x, k) => [x, D.train.y[k], D.train.theta[k]]);
  }

  function drawTrain(poses) {
    drawnBodies = [];
    ctx.save();
    ctx.lineWidth = 1.2 * dpr;
    // the chain: body centre to body centre
    ctx.strokeStyle = "#333"; ctx.beginPath();
    let pen = false;  // a body whose pose is not finite (null) is left out, the chain broken
    poses.forEach((p) => {
      if (p[0] === null || p[1] === null) { pen = false; return; }
      const q = toPx(p[0], p[1]); if (pen) ctx.lineTo(q[0], q[1]); else ctx.moveTo(q[0], q[1]);
      pen = true;
    });
    ctx.stroke();
    poses.forEach((p, k) => {
      if (p[0] === null || p[1] === null || p[2] === null) return;
      const fp = k === 0 ? D.footprints.robot : D.footprints.trailer;
      const corners = rect(p[0], p[1], p[2], fp[0], fp[1]);
      ctx.fillStyle = k === 0 ? COLORS.robot : COLORS.trailer;
      ctx.strokeStyle = k === 0 ? "#7a0f10" : "#0b3d66";
      ctx.globalAlpha = 0.75;
      fillPoly(ctx, corners);
      drawnBodies.push(corners.map((q) => toPx(q[0], q[1])));
      // the heading mark: toward the robot
      const a = toPx(p[0], p[1]);
      const b = toPx(p[0] + 0.35 * fp[0] * Math.cos(p[2]), p[1] + 0.35 * fp[0] * Math.sin(p[2]));
      ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
    });
    ctx.restore();
  }

  let row = 0;
  function draw() {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.drawImage(layer, 0, 0);
    drawTrain(poseAt(row));
  }

  // zoom and pan
  let drag = null;
  canvas.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    const r = canvas.getBoundingClientRect();
    const px = (ev.clientX - r.left) * dpr, py = (ev.clientY - r.top) * dpr;
    const w = toWorld(px, py);
    view.s *= Math.exp(-ev.deltaY * 0.0015);
    view.x0 = w[0] - px / view.s; view.y1 = w[1] + py / view.s;
    redrawLayer(); draw();
  }, {passive: false});
  canvas.addEventListener("mousedown", (ev) => { drag = [ev.clientX, ev.clientY]; });
  window.addEventListener("mouseup", () => { drag = null; });
  canvas.addEventListener("mousemove", (ev) => {
    const r = canvas.getBoundingClientRect();
    const w = toWorld((ev.clientX - r.left) * dpr, (ev.clientY - r.top) * dpr);
    $("readout").textContent = `x = ${w[0].toFixed(2)} m, y = ${w[1].toFixed(2)} m`;
    if (!drag) return;
    view.x0 -= (ev.clientX - drag[0]) * dpr / view.s;
    view.y1 += (ev.clientY - drag[1]) * dpr / view.s;
    drag = [ev.clientX, ev.clientY];
    redrawLayer(); draw();
  });
  canvas.addEventListener("dblclick", () => { fit(); redrawLayer(); draw(); });

  // ---------------------------------------------------------------- legend
  function legend(items) {
    const ul = $("legend");
    items.forEach(([text, css]) => {
      const li = document.createElement("li");
      const i = document.createElement("i"); i.style.cssText = css;
      li.appendChild(i); li.appendChild(document.createTextNode(text)); ul.appendChild(li);
    });
  }
  if (isRun) {
    legend([["robot", `background:${COLORS.robot}`],
            ["trailers", `background:${COLORS.trailer}`],
            ["planned path (last trailer)", `background:${COLORS.path};opacity:.45`],
            ["reference (last trailer)", `border-top:2px dashed ${COLORS.ref};height:0`],
            ["robot trace", `border-top:2px solid ${COLORS.robotTrace};height:0`],
            ["last trailer trace", `border-top:2px solid ${COLORS.lastTrace};height:0`]]);
  } else {
    const b = D.bottleneck;
    legend([["explored (last trailer)", `border-top:2px solid ${COLORS.tree};height:0`],
            ["route through the building", `background:${COLORS.route};opacity:.5`],
            ["best partial plan", `border-top:3px solid ${COLORS.partial};height:0`],
            ["train at the best partial plan: robot", `background:${COLORS.robot}`],
            ["trailers", `background:${COLORS.trailer}`],
            ["motion failures", "border:2px solid #e00000;width:6px;height:6px"],
            ["start", "background:#2ca02c;opacity:.5"], ["goal", "background:#d62728;opacity:.5"]]
           .concat(b ? [[(wideEnough(b) ? "narrowest place of the widest way" :
                          (b.what || "bottleneck")) +
                         ` at (${b.x.toFixed(2)}, ${b.y.toFixed(2)}): ` +
                         `${b.width.toFixed(2)} m wide, ` + (b.needed === null ?
                           "no steady turn fits" : `${b.needed.toFixed(2)} m needed`) +
                         (wideEnough(b) ? " (wide enough: what blocked is elsewhere)" : ""),
                         `border:2px solid ${wideEnough(b) ? COLORS.wideEnough :
                           COLORS.bottleneck};border-radius:50%;width:8px`]]
                      : []));
  }
  if (D.keep_out) legend([[D.keep_out.omitted
    ? `keep-out band ${D.keep_out.margin} m (not drawn: ${D.keep_out.omitted} points)`
    : `keep-out band (clearance ${D.keep_out.margin} m)`,
    `border-top:2px dashed ${COLORS.keepOut};height:0`]]);

  // ---------------------------------------------------------------- plots
  function niceTicks(lo, hi) {  // 3 to 6 round values within [lo, hi], 0 among them if inside
    const raw = (hi - lo) / 4, mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map((f) => f * mag).find((v) => v >= raw) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-12; v += step) {
      out.push(Math.abs(v) < 1e-12 * step ? 0 : v);
    }
    return out;
  }

  function Plot(spec) {
    const box = document.createElement("div"); box.className = "plot";
    const c = document.createElement("canvas");
    const value = document.createElement("div"); value.className = "value";
    box.appendChild(c); box.appendChild(value); $("plots").appendChild(box);
    const g = c.getContext("2d");
    const M = {l: 52, r: 8, t: 18, b: 20};
    let [lo, hi] = range([].concat(...spec.lines.map((ln) => ln.y),
                                   spec.limits.map((lm) => lm.y)));
    if (!(lo <= hi)) { lo = -1; hi = 1; }
    if (hi - lo < 1e-9) { lo -= 1; hi += 1; }
    const padY = 0.06 * (hi - lo); lo -= padY; hi += padY;
    const t0 = D.t[0], t1 = D.t[D.t.length - 1] > t0 ? D.t[D.t.length - 1] : t0 + 1;
    const base = document.createElement("canvas");
    const self = {spec, cursorPx: null};
    const X = (t) => M.l * dpr + (t - t0) / (t1 - t0) * (c.width - (M.l + M.r) * dpr);
    const T = (px) => t0 + (px - M.l * dpr) / (c.width - (M.l + M.r) * dpr) * (t1 - t0);
    const Y = (v) => M.t * dpr + (hi - v) / (hi - lo) * (c.height - (M.t + M.b) * dpr);
    self.resize = function () {
      c.width = Math.max(1, Math.round(c.clientWidth * dpr));
      c.height = Math.max(1, Math.round(c.clientHeight * dpr));
      base.width = c.width; base.height = c.height;
      const b = base.getContext("2d");
      b.fillStyle = "#fff"; b.fillRect(0, 0, base.width, base.height);
      b.font = `${11 * dpr}px system-ui, sans-serif`; b.fillStyle = "#222";
      b.fillText(`${spec.title} [${spec.unit}]`, M.l * dpr, 12 * dpr);
      b.strokeStyle = "#999"; b.lineWidth = dpr;
      b.strokeRect(M.l * dpr, M.t * dpr, c.width - (M.l + M.r) * dpr,
                   c.height - (M.t + M.b) * dpr);
      b.fillStyle = "#444";
      niceTicks(lo, hi).forEach((v) => {
        b.strokeStyle = "#eee"; b.beginPath(); b.moveTo(X(t0), Y(v)); b.lineTo(X(t1), Y(v));
        b.stroke();
        b.fillText(String(+v.toPrecision(6)), 2 * dpr, Y(v) + 4 * dpr);
      });
      b.fillText(`${t0.toFixed(0)} s`, M.l * dpr, c.height - 5 * dpr);
      b.fillText(`${t1.toFixed(0)} s`, c.width - (M.r + 36) * dpr, c.height - 5 * dpr);
      if (lo < 0 && hi > 0) {
        b.strokeStyle = "#ddd"; b.beginPath(); b.moveTo(X(t0), Y(0)); b.lineTo(X(t1), Y(0));
        b.stroke();
      }
      spec.limits.forEach((lm) => {
        b.strokeStyle = "#d62728"; b.setLineDash([6 * dpr, 4 * dpr]); b.beginPath();
        b.moveTo(X(t0), Y(lm.y)); b.lineTo(X(t1), Y(lm.y)); b.stroke(); b.setLineDash([]);
        if (lm.name) {
          b.fillStyle = "#d62728";
          const w = b.measureText(lm.name).width;
          b.fillText(lm.name, X(t1) - w - 4 * dpr, Y(lm.y) + 12 * dpr);
        }
      });
      spec.lines.forEach((ln, k) => {
        b.strokeStyle = ln.color || LINE_COLORS[k % LINE_COLORS.length];
        b.lineWidth = (ln.style === "dashed" ? 1.2 : 1.6) * dpr;
        b.setLineDash(ln.style === "dashed" ? [5 * dpr, 3 * dpr] : []);
        b.beginPath();
        let pen = false;
        ln.y.forEach((v, i) => {
          if (v === null) { pen = false; return; }
          if (pen) b.lineTo(X(D.t[i]), Y(v)); else b.moveTo(X(D.t[i]), Y(v));
          pen = true;
        });
        b.stroke(); b.setLineDash([]);
      });
      // the series' names, right to left at the top
      let x = c.width - M.r * dpr;
      spec.lines.slice().reverse().forEach((ln, k) => {
        const idx = spec.lines.length - 1 - k;
        const w = b.measureText(ln.name).width + 8 * dpr;
        x -= w;
        b.fillStyle = ln.color || LINE_COLORS[idx % LINE_COLORS.length];
        b.fillText(ln.name, x, 12 * dpr);
      });
    };
    self.draw = function (i) {
      g.setTransform(1, 0, 0, 1, 0, 0);
      g.drawImage(base, 0, 0);
      const px = X(D.t[i]);
      self.cursorPx = px;
      g.strokeStyle = "#000"; g.lineWidth = dpr; g.beginPath();
      g.moveTo(px, M.t * dpr); g.lineTo(px, c.height - M.b * dpr); g.stroke();
      value.textContent = spec.lines.map((ln) => `${ln.name} ${ln.y[i] === null ? "-"
        : ln.y[i].toPrecision(4)}`).join("  ");
    };
    self.cursorTime = () => (self.cursorPx === null ? null : T(self.cursorPx));
    c.addEventListener("click", (ev) => {
      const r = c.getBoundingClientRect();
      setTime(T((ev.clientX - r.left) * dpr));
    });
    c.addEventListener("mousemove", (ev) => {
      const r = c.getBoundingClientRect();
      const i = rowAt(T((ev.clientX - r.left) * dpr));
      value.textContent = `t = ${D.t[i].toFixed(2)} s: ` + spec.lines.map((ln) =>
        `${ln.name} ${ln.y[i] === null ? "-" : ln.y[i].toPrecision(4)}`).join("  ");
    });
    return self;
  }
  const plots = isRun ? D.series.map(Plot) : [];
  if (!isRun) $("plots").style.display = "none";

  // ---------------------------------------------------------------- time
  const slider = $("slider");
  function rowAt(t) {  // the view row nearest time t
    let a = 0, b = D.t.length - 1;
    if (t <= D.t[0]) return 0;
    if (t >= D.t[b]) return b;
    while (b - a > 1) { const m = (a + b) >> 1; if (D.t[m] <= t) a = m; else b = m; }
    return (t - D.t[a] <= D.t[b] - t) ? a : b;
  }
  function setRow(i) {
    if (!hasRows) { draw(); return; }
    row = Math.max(0, Math.min(D.t.length - 1, i | 0));
    slider.value = String(row);
    $("time").textContent = `t = ${D.t[row].toFixed(2)} s`;
    draw();
    plots.forEach((p) => p.draw(row));
  }
  function setTime(t) { simTime = t; setRow(rowAt(t)); }
  let simTime = 0, playing = false, lastFrame = null, frames = [];
  function tick(now) {
    if (!playing) return;
    if (lastFrame !== null) simTime += (now - lastFrame) / 1000 * parseFloat($("speed").value);
    lastFrame = now;
    frames.push(now);
    while (frames.length && now - frames[0] > 1000) frames.shift();
    if (simTime >= D.t[D.t.length - 1]) { setTime(D.t[D.t.length - 1]); pause(); return; }
    setRow(rowAt(simTime));
    requestAnimationFrame(tick);
  }
  function play() {
    if (row >= D.t.length - 1) simTime = D.t[0];
    playing = true; lastFrame = null; $("play").textContent = "\u23f8 pause";
    requestAnimationFrame(tick);
  }
  function pause() { playing = false; $("play").textContent = "\u25b6 play"; }
  if (hasRows) {
    slider.max = String(D.t.length - 1);
    slider.addEventListener("input", () => { setRow(parseInt(slider.value, 10));
                                             simTime = D.t[row]; });
    $("play").addEventListener("click", () => (playing ? pause() : play()));
  } else {
    $("controls").style.display = "none";
  }

  // ---------------------------------------------------------------- summary
  function flatten(obj, prefix, out) {
    Object.entries(obj || {}).forEach(([k, v]) => {
      const key = prefix ? `${prefix}.${k}` : k;
      if (Array.isArray(v) && v.length && typeof v[0] === "object" && v[0] !== null) {
        v.forEach((item, j) => flatten(item, `${key}[${j}]`, out));
      } else if (v !== null && typeof v === "object" && !Array.isArray(v)) {
        flatten(v, key, out);
      } else {
        const fmt = (x) => (typeof x === "number" && !Number.isInteger(x) ? x.toPrecision(4)
                            : String(x));
        out.push([key, Array.isArray(v) ? v.map(fmt).join(", ") : fmt(v)]);
      }
    });
    return out;
  }
  const table = $("summary");
  flatten(D.summary, "", []).forEach(([k, v]) => {
    const tr = document.createElement("tr");
    const th = document.createElement("th"); th.textContent = k;
    const td = document.createElement("td"); td.textContent = v;
    tr.appendChild(th); tr.appendChild(td); table.appendChild(tr);
  });

  // ---------------------------------------------------------------- for tests and scripts
  window.pushtrainReport = {
    ready: false,
    setRow, setTime, play, pause,
    state() {  // what is drawn, read back from the canvas coordinates
      const bodies = drawnBodies.map((corners) => {
        const w = corners.map((p) => toWorld(p[0], p[1]));
        const x = w.reduce((a, q) => a + q[0], 0) / 4, y = w.reduce((a, q) => a + q[1], 0) / 4;
        // corners 0 and 3 are the front ones (toward the robot)
        const fx = 0.5 * (w[0][0] + w[3][0]) - x, fy = 0.5 * (w[0][1] + w[3][1]) - y;
        return [x, y, Math.atan2(fy, fx)];
      });
      return {kind: D.kind, row, resultRow: isRun ? D.rows[row] : null,
              t: isRun ? D.t[row] : null, bodies,
              cursors: plots.map((p) => p.cursorTime()), playing,
              fps: frames.length, bottleneck: drawnBottleneck};
    },
  };
  function ready() {
    resize();
    setRow(0);
    window.pushtrainReport.ready = true;
  }
  window.addEventListener("resize", resize);
  if (D.map) {
    mapImage = new Image();
    mapImage.onload = ready;
    mapImage.src = "data:image/png;base64," + D.map.png;
  } else {
    ready();
  }
})();
