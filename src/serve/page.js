// rattle explore: the page. It asks the server (src/serve.rs) for the map of a view (coarse
// first, then the configured grid), draws the layer chosen, zooms on a dragged box (the URL's
// hash holds the view, so that a reload, a shared link and the browser's back and forward
// restore it) and shows the point of a clicked cell. `window.rattle` holds what the page
// received, for tests and for the curious.
"use strict";

const M = { left: 78, right: 16, top: 16, bottom: 52 };
const canvas = document.getElementById("map");
const ctx = canvas.getContext("2d");
const box = document.getElementById("box");
const state = (window.rattle = {
  svg: () => svgOfView(),
  base: null, view: null, map: null, point: null, layer: "class", busy: false, loads: 0,
  bounds: null,
});

function status(text, bad) {
  const s = document.getElementById("status");
  s.textContent = text;
  s.className = bad ? "error" : "";
}

async function call(url, body) {
  const r = await fetch(url, body === undefined ? {} : {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
  });
  const j = await r.json();
  if (!r.ok) {
    const e = new Error(j.error || r.statusText);
    e.status = r.status;
    throw e;
  }
  return j;
}

// The plotting area, canvas pixels.
function area() {
  return { x: M.left, y: M.top, w: canvas.width - M.left - M.right,
    h: canvas.height - M.top - M.bottom };
}

function viewFromHash() {
  const h = new URLSearchParams(location.hash.slice(1));
  const keys = ["x_from", "x_to", "y_from", "y_to"];
  if (!keys.every((k) => h.has(k))) return null;
  const v = {};
  for (const k of keys) v[k] = Number(h.get(k));
  // A volume's plane: its z value.
  if (h.has("z")) v.z = Number(h.get("z"));
  return keys.concat(h.has("z") ? ["z"] : []).every((k) => Number.isFinite(v[k])) ? v : null;
}

function hashOf(v) {
  const h = { x_from: v.x_from, x_to: v.x_to, y_from: v.y_from, y_to: v.y_to };
  if (v.z !== undefined && v.z !== null) h.z = v.z;
  return "#" + new URLSearchParams(h).toString();
}

function sameView(v, w) {
  return v.x_from === w.x_from && v.x_to === w.x_to && v.y_from === w.y_from &&
    v.y_to === w.y_to && (v.z ?? null) === (w.z ?? null);
}

// A volume's slider: one step per slice, showing the view's z.
function syncSlider(v) {
  const z = state.base && state.base.z;
  if (!z) return;
  const i = z.values.reduce((b, x, k) => (Math.abs(x - v.z) < Math.abs(z.values[b] - v.z) ? k : b), 0);
  const s = document.getElementById("z");
  s.value = String(i);
  document.getElementById("zval").textContent = `${z.param} = ${v.z}`;
}

// Round ticks over [a, b].
function ticks(a, b, n) {
  const span = Math.abs(b - a);
  if (!(span > 0)) return [a];
  const raw = span / n;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw);
  const lo = Math.min(a, b), hi = Math.max(a, b);
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) {
    out.push(Number(t.toPrecision(12)));
  }
  return out;
}

// ColorBrewer RdBu (the PNG's exponent scale) and a light-to-dark sequential scale.
const RDBU = [[0x21, 0x66, 0xac], [0x92, 0xc5, 0xde], [0xf7, 0xf7, 0xf7], [0xf4, 0xa5, 0x82],
  [0xb2, 0x18, 0x2b]];
const SEQ = [[0xff, 0xff, 0xcc], [0xa1, 0xda, 0xb4], [0x41, 0xb6, 0xc4], [0x22, 0x5e, 0xa8],
  [0x0c, 0x2c, 0x84]];

function ramp(stops, t) {
  t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(t)), f = t - i;
  return stops[i].map((c, k) => Math.round(c + (stops[i + 1][k] - c) * f));
}

// The colour of each cell of the layer shown, and the legend's lines for it.
function colours(m, layer) {
  const n = m.nx * m.ny;
  const out = new Array(n);
  if (layer === "class") {
    for (let i = 0; i < n; i++) out[i] = m.legend[m.shown[i]].rgb;
    return { out, legend: m.legend.map((e) => ({ rgb: e.rgb, label: e.label, cells: e.cells })) };
  }
  const values = (m.layers.find((l) => l[0] === layer) || [null, []])[1];
  const finite = values.filter((v) => v !== null && Number.isFinite(v));
  // A loop, not Math.min(...finite): spreading over 125k values and more overflows the stack.
  let lo = Infinity, hi = -Infinity;
  for (const v of finite) { if (v < lo) lo = v; if (v > hi) hi = v; }
  let stops = SEQ, f = (v) => (v - lo) / (hi - lo || 1);
  if (layer === "lyapunov") {
    const a = Math.max(Math.abs(lo), Math.abs(hi)) || 1;
    stops = RDBU; lo = -a; hi = a; f = (v) => (v + a) / (2 * a);
  } else if (layer === "settle") {
    const l = (v) => Math.log10(Math.max(1, v));
    const a = l(lo), b = l(hi);
    f = (v) => (l(v) - a) / (b - a || 1);
  }
  for (let i = 0; i < n; i++) {
    const v = values[i];
    out[i] = v === null || !Number.isFinite(v) ? [190, 190, 190] : ramp(stops, f(v));
  }
  const legend = finite.length ? [
    { rgb: ramp(stops, 0), label: `${lo.toPrecision(4)} (lowest)` },
    { rgb: ramp(stops, 1), label: `${hi.toPrecision(4)} (highest)` },
    { rgb: [190, 190, 190], label: "no value" },
  ] : [{ rgb: [190, 190, 190], label: "no value in this view" }];
  return { out, legend };
}

// The layer menu: the class and the scalar layers this map has (the risk where asked for).
const LABELS = {
  class: "class", lyapunov: "largest Lyapunov exponent", multiplier: "leading multiplier |mu|",
  settle: "settle time (periods)", risk: "risk: P(another class) under map.risk's errors",
};
function syncLayers(m) {
  const sel = document.getElementById("layer");
  const names = ["class", ...m.layers.map((l) => l[0])];
  if ([...sel.options].map((o) => o.value).join() !== names.join()) {
    sel.replaceChildren(...names.map((n) => new Option(LABELS[n] || n, n)));
  }
  if (!names.includes(state.layer)) state.layer = "class";
  sel.value = state.layer;
}

function draw() {
  const m = state.map;
  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  if (!m) return;
  syncLayers(m);
  const a = area();
  const { out, legend } = colours(m, state.layer);
  const img = new ImageData(m.nx, m.ny);
  for (let iy = 0; iy < m.ny; iy++) {
    for (let ix = 0; ix < m.nx; ix++) {
      const c = out[iy * m.nx + ix];
      const p = 4 * ((m.ny - 1 - iy) * m.nx + ix); // row 0 of the grid is the bottom
      img.data[p] = c[0]; img.data[p + 1] = c[1]; img.data[p + 2] = c[2]; img.data[p + 3] = 255;
    }
  }
  const off = document.createElement("canvas");
  off.width = m.nx; off.height = m.ny;
  off.getContext("2d").putImageData(img, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(off, a.x, a.y, a.w, a.h);
  // Axes.
  const v = m.view;
  ctx.strokeStyle = "#000"; ctx.fillStyle = "#000"; ctx.lineWidth = 1;
  ctx.strokeRect(a.x + 0.5, a.y + 0.5, a.w, a.h);
  ctx.font = "12px 'DejaVu Sans', sans-serif";
  ctx.textAlign = "center"; ctx.textBaseline = "top";
  for (const t of ticks(v.x_from, v.x_to, 6)) {
    const px = a.x + ((t - v.x_from) / (v.x_to - v.x_from)) * a.w;
    ctx.beginPath(); ctx.moveTo(px, a.y + a.h); ctx.lineTo(px, a.y + a.h + 5); ctx.stroke();
    ctx.fillText(String(t), px, a.y + a.h + 7);
  }
  ctx.textAlign = "right"; ctx.textBaseline = "middle";
  for (const t of ticks(v.y_from, v.y_to, 6)) {
    const py = a.y + a.h - ((t - v.y_from) / (v.y_to - v.y_from)) * a.h;
    ctx.beginPath(); ctx.moveTo(a.x - 5, py); ctx.lineTo(a.x, py); ctx.stroke();
    ctx.fillText(String(t), a.x - 7, py);
  }
  // The typed boundaries of this view, where asked for.
  const b = boundsOf(m);
  const toPx = (q) => [a.x + ((q[0] - v.x_from) / (v.x_to - v.x_from)) * a.w,
    a.y + a.h - ((q[1] - v.y_from) / (v.y_to - v.y_from)) * a.h];
  if (b) {
    ctx.save();
    ctx.beginPath(); ctx.rect(a.x, a.y, a.w, a.h); ctx.clip();
    ctx.lineWidth = 2;
    for (const c of b.curves) {
      ctx.strokeStyle = ctx.fillStyle = `rgb(${b.colours[c.type].join(",")})`;
      const pts = c.points.map(toPx);
      if (pts.length === 1) {
        ctx.beginPath(); ctx.arc(pts[0][0], pts[0][1], 2, 0, 2 * Math.PI); ctx.fill();
        continue;
      }
      ctx.beginPath();
      pts.forEach((q, k) => (k ? ctx.lineTo(q[0], q[1]) : ctx.moveTo(q[0], q[1])));
      ctx.stroke();
    }
    ctx.restore();
  }
  for (const id of ["ex-bcsv", "ex-bpng"]) document.getElementById(id).hidden = !b;
  const bl = document.getElementById("blegend");
  bl.replaceChildren(...(b ? Object.entries(countTypes(b)).map(([t, n]) => {
    const li = document.createElement("li");
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = `rgb(${b.colours[t].join(",")})`;
    li.append(sw, document.createTextNode(`${t.replace(/_/g, " ")} (${n} points)`));
    return li;
  }) : []));
  // The clicked point, where it is in this view.
  const p = state.point;
  if (p) {
    const px = a.x + ((p.x - v.x_from) / (v.x_to - v.x_from)) * a.w;
    const py = a.y + a.h - ((p.y - v.y_from) / (v.y_to - v.y_from)) * a.h;
    if (px >= a.x && px <= a.x + a.w && py >= a.y && py <= a.y + a.h) {
      ctx.strokeStyle = "#fff"; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.arc(px, py, 6, 0, 2 * Math.PI); ctx.stroke();
      ctx.strokeStyle = "#d00"; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.arc(px, py, 6, 0, 2 * Math.PI); ctx.stroke();
      ctx.lineWidth = 1; ctx.strokeStyle = "#000";
    }
  }
  ctx.textAlign = "center"; ctx.textBaseline = "bottom";
  ctx.fillText(m.x_param, a.x + a.w / 2, canvas.height - 4);
  ctx.save(); ctx.translate(14, a.y + a.h / 2); ctx.rotate(-Math.PI / 2);
  ctx.textBaseline = "middle"; ctx.fillText(m.y_param, 0, 0); ctx.restore();
  // Legend.
  const ul = document.getElementById("legend");
  ul.replaceChildren(...legend.map((e) => {
    const li = document.createElement("li");
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = `rgb(${e.rgb.join(",")})`;
    const n = e.cells === undefined ? "" : ` (${e.cells} cells)`;
    li.append(sw, document.createTextNode(e.label + n));
    return li;
  }));
  document.getElementById("where").textContent =
    `${m.x_param} ${v.x_from} .. ${v.x_to}, ${m.y_param} ${v.y_from} .. ${v.y_to}, ` +
    (v.z !== undefined && state.base.z ? `${state.base.z.param} = ${v.z}, ` : "") +
    `${m.nx} x ${m.ny}${m.coarse ? " (coarse first picture, without the long look)" : ""}`;
}

// The boundaries computed for the view `m` shows, if any.
function boundsOf(m) {
  const b = state.bounds;
  if (!b || !m || m.coarse || !document.getElementById("bounds").checked) return null;
  return sameView(m.view, b.view) ? b : null;
}

function countTypes(b) {
  const n = {};
  for (const p of b.points) n[p.type] = (n[p.type] || 0) + 1;
  return n;
}

// The boundaries of the view shown (once its map is at the configured grid).
async function bounds() {
  const m = state.map;
  if (!document.getElementById("bounds").checked || !m || m.coarse || boundsOf(m)) return;
  const token = state.loads;
  state.busy = true;
  status("boundaries...");
  watch("boundaries", token);
  try {
    const b = await call("/api/boundaries", { view: m.view });
    if (state.loads !== token) return;
    state.bounds = b;
    state.busy = false;
    status(`boundaries: ${b.points.filter((p) => p.located).length} changes located on ` +
      `${b.edges} edges in ${b.seconds.toFixed(2)} s`);
    draw();
    if (state.point) showNearest(state.point);
  } catch (e) {
    if (state.loads !== token) return;
    state.busy = false;
    if (e.status !== 409) status(e.message, true);
  }
}

// The boundary point nearest to `p` (in cells of this view), in the panel.
function showNearest(p) {
  const m = state.map, b = boundsOf(m);
  const old = document.getElementById("nearest");
  if (old) old.remove();
  if (!b || !b.points.length) return;
  const v = m.view;
  const cx = (x) => ((x - v.x_from) / (v.x_to - v.x_from)) * m.nx;
  const cy = (y) => ((y - v.y_from) / (v.y_to - v.y_from)) * m.ny;
  let best = null, dist = Infinity;
  for (const q of b.points) {
    const d = Math.hypot(cx(q.x) - cx(p.x), cy(q.y) - cy(p.y));
    if (d < dist) { dist = d; best = q; }
  }
  const div = document.createElement("p");
  div.id = "nearest";
  const period = best.period ? `, period-${best.period} cycle` : "";
  const why = best.reason ? ` (${best.reason})` : "";
  div.textContent = `nearest boundary: ${best.type.replace(/_/g, " ")}${period} between ` +
    `${best.classes[0]} and ${best.classes[1]}, at ${m.x_param} = ${best.x.toPrecision(6)}, ` +
    `${m.y_param} = ${best.y.toPrecision(6)}: ${dist.toFixed(2)} cells away${why}`;
  const t = document.querySelector("#panel table");
  if (t) t.after(div);
}

// Progress while a computation runs: of this load's phase only (a phase's watcher stops when
// the next phase starts). The count grows with the work found on the way (the long look's
// stages, the recurrence search's windows); past it only the stable cycles carried between
// cells and the map's assembly remain, which the bar says, not "100%".
async function watch(label, token, phase) {
  const current = () => state.loads === token && state.phase === phase && state.busy;
  while (current()) {
    try {
      const p = await call("/api/progress");
      if (p.busy && p.total > 0 && current()) {
        status(p.done >= p.total
          ? `${label}: carrying stable cycles between cells...`
          : `${label}: ${Math.floor((100 * p.done) / p.total)}%`);
      }
    } catch (e) { /* the next poll tells */ }
    await new Promise((r) => setTimeout(r, 250));
  }
}

// Loads `view`: the coarse picture, then the configured grid.
async function load(view, push) {
  if (push) history.pushState(null, "", hashOf(view));
  state.view = view;
  syncSlider(view);
  const token = ++state.loads;
  state.busy = true;
  try {
    for (const coarse of [true, false]) {
      const label = coarse ? "coarse picture" : `${state.base.nx} x ${state.base.ny} map`;
      const phase = (state.phase || 0) + 1;
      state.phase = phase;
      status(`${label}...`);
      watch(label, token, phase);
      const m = await call("/api/map", { view, coarse });
      if (state.loads !== token) return;
      state.map = m;
      draw();
    }
    state.busy = false;
    const t = state.map.timings;
    status(`done: ${t.wall_s.toFixed(2)} s (${t.round_trips || 0} round trips)`);
    const c = await fetch("/api/export/command");
    if (c.ok) document.getElementById("command").textContent = await c.text();
    bounds();
  } catch (e) {
    if (state.loads !== token) return;
    state.busy = false;
    if (e.status !== 409) status(e.message, true);
  }
}

// The view as the page shows it (the layer chosen, its legend, the boundaries where shown), as
// an SVG document: each row's runs of one colour as one rectangle, the axes and the legend as
// text, so that it prints sharp at any size.
function svgOfView() {
  const m = state.map;
  if (!m) return null;
  const { out, legend } = colours(m, state.layer);
  const W = 1000, H = 640, L = 90, R = 300, T = 20, B = 60;
  const aw = W - L - R, ah = H - T - B, v = m.view;
  const esc = (t) => String(t).replace(/&/g, "&amp;").replace(/</g, "&lt;");
  const rgb = (c) => `rgb(${c.join(",")})`;
  const parts = [`<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H}" ` +
    `viewBox="0 0 ${W} ${H}" font-family="DejaVu Sans, sans-serif" font-size="12">`,
    `<rect width="${W}" height="${H}" fill="#fff"/>`, `<g shape-rendering="crispEdges">`];
  const cw = aw / m.nx, ch = ah / m.ny;
  for (let iy = 0; iy < m.ny; iy++) {
    for (let ix = 0; ix < m.nx;) {
      const c = out[iy * m.nx + ix];
      let e = ix + 1;
      while (e < m.nx && out[iy * m.nx + e].join() === c.join()) e++;
      const y = T + ah - (iy + 1) * ch;
      parts.push(`<rect class="cells" x="${(L + ix * cw).toFixed(3)}" y="${y.toFixed(3)}" ` +
        `width="${((e - ix) * cw).toFixed(3)}" height="${ch.toFixed(3)}" fill="${rgb(c)}" ` +
        `data-row="${iy}" data-from="${ix}" data-to="${e}"/>`);
      ix = e;
    }
  }
  parts.push("</g>");
  const X = (x) => L + ((x - v.x_from) / (v.x_to - v.x_from)) * aw;
  const Y = (y) => T + ah - ((y - v.y_from) / (v.y_to - v.y_from)) * ah;
  const b = boundsOf(m);
  if (b) {
    for (const c of b.curves) {
      const pts = c.points.map((q) => `${X(q[0]).toFixed(2)},${Y(q[1]).toFixed(2)}`);
      const col = rgb(b.colours[c.type]);
      parts.push(pts.length === 1
        ? `<circle cx="${pts[0].split(",")[0]}" cy="${pts[0].split(",")[1]}" r="2" fill="${col}"/>`
        : `<polyline points="${pts.join(" ")}" fill="none" stroke="${col}" stroke-width="2"/>`);
    }
  }
  parts.push(`<rect x="${L}" y="${T}" width="${aw}" height="${ah}" fill="none" stroke="#000"/>`);
  for (const t of ticks(v.x_from, v.x_to, 6)) {
    parts.push(`<line x1="${X(t)}" y1="${T + ah}" x2="${X(t)}" y2="${T + ah + 5}" stroke="#000"/>`,
      `<text x="${X(t)}" y="${T + ah + 18}" text-anchor="middle">${t}</text>`);
  }
  for (const t of ticks(v.y_from, v.y_to, 6)) {
    parts.push(`<line x1="${L - 5}" y1="${Y(t)}" x2="${L}" y2="${Y(t)}" stroke="#000"/>`,
      `<text x="${L - 8}" y="${Y(t) + 4}" text-anchor="end">${t}</text>`);
  }
  parts.push(`<text x="${L + aw / 2}" y="${H - 12}" text-anchor="middle">${esc(m.x_param)}</text>`,
    `<text transform="translate(18 ${T + ah / 2}) rotate(-90)" text-anchor="middle">` +
    `${esc(m.y_param)}</text>`);
  const rows = legend.map((e) => [e.rgb, e.label + (e.cells === undefined ? "" : ` (${e.cells} cells)`)]);
  if (b) {
    for (const [t, n] of Object.entries(countTypes(b))) {
      rows.push([b.colours[t], `${t.replace(/_/g, " ")} (${n} points)`]);
    }
  }
  rows.forEach(([c, label], k) => {
    const y = T + 14 * k;
    parts.push(`<rect x="${W - R + 20}" y="${y}" width="10" height="10" fill="${rgb(c)}" stroke="#999"/>`,
      `<text x="${W - R + 36}" y="${y + 9}">${esc(label)}</text>`);
  });
  parts.push("</svg>");
  return parts.join("\n");
}

// The cell under canvas pixel (px, py), and its centre's parameters.
function cellAt(px, py) {
  const m = state.map, a = area(), v = m.view;
  const ix = Math.floor(((px - a.x) / a.w) * m.nx);
  const iy = Math.floor(((a.y + a.h - py) / a.h) * m.ny);
  if (ix < 0 || iy < 0 || ix >= m.nx || iy >= m.ny) return null;
  return { ix, iy,
    x: v.x_from + ((v.x_to - v.x_from) * (ix + 0.5)) / m.nx,
    y: v.y_from + ((v.y_to - v.y_from) * (iy + 0.5)) / m.ny };
}

function row(k, v) {
  const tr = document.createElement("tr");
  const a = document.createElement("td"), b = document.createElement("td");
  a.textContent = k; b.textContent = v;
  tr.append(a, b);
  return tr;
}

async function point(c) {
  const panel = document.getElementById("panel");
  panel.replaceChildren(document.createTextNode(`computing the point at cell (${c.ix}, ${c.iy})...`));
  try {
    const p = await call("/api/point", { view: state.map.view, x: c.x, y: c.y });
    state.point = p;
    draw();
    const r = p.report;
    const t = document.createElement("table");
    const mult = (r.multipliers || []).map((z) => Math.hypot(z[0], z[1]).toPrecision(4));
    t.append(
      row(p.x_param, String(p.x)), row(p.y_param, String(p.y)),
      row("class", r.class), row("period", r.period === null ? "-" : String(r.period)),
      row("rule", String(r.rule)),
      row("|multipliers|", mult.length ? mult.join(", ") : "-"),
      // A confirmed cycle's exponent is its own (ln|mu_1| over its period); the run's beside it.
      r.multipliers && r.lyapunov_se === 0
        ? row("Lyapunov exponent", `${r.lyapunov.toPrecision(4)} (the cycle's; the run's window ` +
            `${r.run_lyapunov[0].toPrecision(4)} +- ${r.run_lyapunov[1].toPrecision(2)})`)
        : row("Lyapunov exponent", `${r.lyapunov.toPrecision(4)} +- ${r.lyapunov_se.toPrecision(2)}`),
      row("settle (periods)", String(r.settle)),
      row("periods integrated", String(r.periods)),
      row("periods tried by Newton", (r.tried_periods || []).join(", ") || "-"),
    );
    // What the map's carry found at this cell (a point alone has no neighbours to carry from).
    const m = state.map;
    if (m && !m.coarse && c.ix < m.nx && c.iy < m.ny) {
      const k = m.coexist[c.iy * m.nx + c.ix];
      t.append(row("coexisting (the map's carry)",
        k ? `a stable period-${k} cycle carried from a neighbouring cell` : "none found"));
    }
    panel.replaceChildren(t);
    panel.dataset.cls = r.class;
    showNearest(p);
    if (p.figure) {
      const img = document.createElement("img");
      img.alt = "time series, phase portrait, Poincare section";
      img.src = `/api/point.png?n=${Date.now()}`;
      panel.append(img);
    }
  } catch (e) {
    if (e.status !== 409) panel.replaceChildren(document.createTextNode(e.message));
  }
}

// Drag a box to zoom, click to see a point.
let down = null;
function local(ev) {
  const r = canvas.getBoundingClientRect();
  return [ev.clientX - r.left, ev.clientY - r.top];
}
canvas.addEventListener("mousedown", (ev) => { down = local(ev); });
canvas.addEventListener("mousemove", (ev) => {
  if (!down) return;
  const [x, y] = local(ev);
  Object.assign(box.style, {
    display: "block", left: `${Math.min(x, down[0])}px`, top: `${Math.min(y, down[1])}px`,
    width: `${Math.abs(x - down[0])}px`, height: `${Math.abs(y - down[1])}px`,
  });
});
window.addEventListener("mouseup", (ev) => {
  if (!down || !state.map) { down = null; return; }
  const [x, y] = local(ev);
  const [x0, y0] = down;
  down = null;
  box.style.display = "none";
  const a = area(), v = state.map.view;
  if (Math.abs(x - x0) > 5 && Math.abs(y - y0) > 5) {
    const px = (p) => v.x_from + ((Math.min(Math.max(p, a.x), a.x + a.w) - a.x) / a.w) * (v.x_to - v.x_from);
    const py = (p) => v.y_from + ((a.y + a.h - Math.min(Math.max(p, a.y), a.y + a.h)) / a.h) * (v.y_to - v.y_from);
    const nv = { x_from: px(Math.min(x, x0)), x_to: px(Math.max(x, x0)),
      y_from: py(Math.max(y, y0)), y_to: py(Math.min(y, y0)) };
    if (v.z !== undefined) nv.z = v.z;
    load(nv, true);
  } else {
    const c = cellAt(x, y);
    if (c) point(c);
  }
});

document.getElementById("bounds").addEventListener("change", () => { draw(); bounds(); });
document.getElementById("ex-svg").addEventListener("click", (ev) => {
  ev.preventDefault();
  const svg = svgOfView();
  if (!svg) return;
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([svg], { type: "image/svg+xml" }));
  a.download = "view.svg";
  a.click();
  URL.revokeObjectURL(a.href);
});
document.getElementById("layer").addEventListener("change", (ev) => {
  state.layer = ev.target.value;
  draw();
});
document.getElementById("back").addEventListener("click", () => history.back());
document.getElementById("forward").addEventListener("click", () => history.forward());
// The configured ranges; a volume's plane stays where the slider is.
document.getElementById("home").addEventListener("click", () => {
  const v = { ...state.base.view };
  if (state.view && state.view.z !== undefined) v.z = state.view.z;
  load(v, true);
});
// The slider names the slice as it moves and loads it where it stops.
document.getElementById("z").addEventListener("input", (ev) => {
  const z = state.base.z;
  document.getElementById("zval").textContent = `${z.param} = ${z.values[Number(ev.target.value)]}`;
});
document.getElementById("z").addEventListener("change", (ev) => {
  const z = state.base.z.values[Number(ev.target.value)];
  load({ ...(state.view || state.base.view), z }, true);
});
window.addEventListener("popstate", () => load(viewFromHash() || state.base.view, false));

(async () => {
  try {
    state.base = await call("/api/base");
    if (state.base.z) {
      const s = document.getElementById("z");
      s.max = String(state.base.z.values.length - 1);
      document.getElementById("zname").textContent = state.base.z.label;
      document.getElementById("zpick").hidden = false;
    }
    const v = viewFromHash();
    if (!v) history.replaceState(null, "", hashOf(state.base.view));
    load(v || state.base.view, false);
  } catch (e) {
    status(e.message, true);
  }
})();
