// poibench live view: one WebSocket, an init message (map, colours), then frame messages.
// The map is SVG in metres, map frame x right and y up (drawn as (x, -y)), in the
// competition's conventions: 1 m checkerboard, 0.5 m grid, walls (0,40,120), path
// (120,0,240), markers of radius 0.175 m with their id in white. In replay the init message
// also carries the trial's funnel (funnel.csv rows) and the ground truth (truth.csv), drawn as
// small hollow markers in the type's box colour; picking one shows its funnel.
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";
const $ = (id) => document.getElementById(id);
let init = null;
let path = [];
let replay = false;
let seekTimer = null;

function el(name, attrs, parent) {
  const e = document.createElementNS(SVG_NS, name);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function setStatus(text) { $("status").textContent = text; }

function drawMap() {
  const svg = $("map");
  svg.innerHTML = "";
  const [x0, y0, x1, y1] = init.bounds;
  svg.setAttribute("viewBox", `${x0} ${-y1} ${x1 - x0} ${y1 - y0}`);
  const bg = el("g", {id: "background"}, svg);
  for (let x = Math.floor(x0); x < x1; x++) {
    for (let y = Math.floor(y0); y < y1; y++) {
      const even = (Math.abs(x) + Math.abs(y)) % 2 === 0;
      el("rect", {x: x, y: -(y + 1), width: 1, height: 1, fill: even ? "rgb(226,226,227)" : "rgb(237,237,238)"}, bg);
    }
  }
  for (let x = Math.floor(x0 * 2) / 2; x <= x1; x += 0.5) {
    el("line", {x1: x, y1: -y1, x2: x, y2: -y0, stroke: "rgb(190,190,191)", "stroke-width": 0.01}, bg);
  }
  for (let y = Math.floor(y0 * 2) / 2; y <= y1; y += 0.5) {
    el("line", {x1: x0, y1: -y, x2: x1, y2: -y, stroke: "rgb(190,190,191)", "stroke-width": 0.01}, bg);
  }
  const walls = el("g", {id: "walls"}, svg);
  for (const [ax, ay, bx, by] of init.walls) {
    el("line", {x1: ax, y1: -ay, x2: bx, y2: -by, stroke: "rgb(0,40,120)", "stroke-width": 0.05,
                "stroke-linecap": "square"}, walls);
  }
  el("polyline", {id: "path", fill: "none", stroke: "rgb(120,0,240)", "stroke-width": 0.04,
                  "stroke-linejoin": "round"}, svg);
  el("g", {id: "ellipses"}, svg);
  el("g", {id: "truth"}, svg);
  el("g", {id: "markers"}, svg);
  el("polygon", {id: "robot", points: "0.25,0 -0.15,0.12 -0.15,-0.12", fill: "rgb(120,0,240)",
                 stroke: "#fff", "stroke-width": 0.02, visibility: "hidden"}, svg);
}

function drawPath(n) {
  const pts = path.slice(0, n).map(([x, y]) => `${x},${-y}`).join(" ");
  $("path").setAttribute("points", pts);
}

// 2-sigma ellipse of a 2x2 covariance: semi-axes 2 sqrt(eigenvalues), angle of the major axis
function ellipse(cov) {
  const a = cov[0][0], b = cov[0][1], d = cov[1][1];
  const tr = (a + d) / 2, det = Math.sqrt(Math.max(((a - d) / 2) ** 2 + b * b, 0));
  const l1 = tr + det, l2 = Math.max(tr - det, 0);
  const angle = Math.atan2(l1 - a, b || 1e-12) * 180 / Math.PI;
  return {rx: 2 * Math.sqrt(l1), ry: 2 * Math.sqrt(l2), angle: angle};
}

function drawMarkers(objs) {
  const markers = $("markers"), ells = $("ellipses");
  markers.innerHTML = "";
  ells.innerHTML = "";
  const r = 0.175;
  for (const o of objs) {
    const color = init.marker_colors[o.type] || "rgb(255,100,30)";
    const e = ellipse(o.cov);
    el("ellipse", {cx: 0, cy: 0, rx: e.rx, ry: e.ry, fill: color, "fill-opacity": 0.15, stroke: color,
                   "stroke-width": 0.015, transform: `translate(${o.x} ${-o.y}) rotate(${-e.angle})`}, ells);
    const g = el("g", {class: "marker", "data-id": o.id, transform: `translate(${o.x} ${-o.y})`}, markers);
    if ((init.marker_shapes[o.type] || "diamond") === "circle") {
      el("circle", {r: r, fill: color}, g);
    } else {
      el("polygon", {points: `0,${-r} ${r},0 0,${r} ${-r},0`, fill: color}, g);
    }
    const t = el("text", {x: 0, y: 0}, g);
    t.textContent = String(o.id);
    el("title", {}, g).textContent = `${o.id}: ${o.name}`;
  }
}

function drawRobot(pose) {
  const robot = $("robot");
  if (!pose) { robot.setAttribute("visibility", "hidden"); return; }
  const [x, y, yaw] = pose;
  robot.setAttribute("transform", `translate(${x} ${-y}) rotate(${-yaw * 180 / Math.PI})`);
  robot.setAttribute("visibility", "visible");
}

function fmtTime(t) {
  const m = Math.floor(t / 60), s = (t - 60 * m).toFixed(1).padStart(4, "0");
  return `${m}:${s}`;
}

function showDetections(dets) {
  const ul = $("detections");
  ul.innerHTML = "";
  if (!dets.length) { ul.innerHTML = '<li class="none">none</li>'; return; }
  for (const d of dets) {
    const li = document.createElement("li");
    li.className = "detection";
    li.style.borderLeftColor = init.box_colors[d.type] || "#888";
    let text = `${d.name} (${Math.round(d.conf * 100)}%)`;
    if (d.track !== null && d.track !== undefined) text += ` · track ${d.track}`;
    if (d.report !== null && d.report !== undefined) text += ` · #${d.report}`;
    li.textContent = text;
    ul.appendChild(li);
  }
}

function showTable(objs) {
  const body = $("pois").querySelector("tbody");
  body.innerHTML = "";
  for (const o of [...objs].reverse()) {
    const tr = document.createElement("tr");
    for (const [v, num] of [[o.id, true], [fmtTime(o.t), true], [o.type, false], [o.name, false],
                            [o.x.toFixed(2), true], [o.y.toFixed(2), true], [o.z.toFixed(2), true]]) {
      const td = document.createElement("td");
      td.textContent = v;
      if (num) td.className = "num";
      tr.appendChild(td);
    }
    body.appendChild(tr);
  }
}

// ------------------------------------------------------------------ funnel (replay)
// The stages an object passes, with the cause that charges its points to the first it did not
// pass (docs/RULES.md "The funnel"); the counts are frames.
const STAGES = [["in view", "in_view", "not in view"], ["boxed", "boxed", "not boxed"],
                ["typed", "typed", "wrong type"], ["localised", "localised", "not localised"],
                ["read", "read", "not read"]];
const dash = (v, unit) => (v === null || v === undefined || v === "" ? "—" : `${v}${unit || ""}`);
const boxColor = (type) => init.box_colors[type] || "#888";

const PICK_RADIUS_M = 0.25;  // a click on the map this near an object picks it (reports may cover it)

function drawTruth() {
  const g = $("truth"), r = 0.12;
  if ((init.truth || []).length) {
    $("map").classList.add("pickable");
    $("map").addEventListener("click", pickOnMap);
  }
  for (const o of init.truth || []) {
    const m = el("g", {class: "truth", "data-id": o.id, transform: `translate(${o.x} ${-o.y})`}, g);
    // hollow, under the reports' markers (a found object's is covered by its report); a dark halo
    // keeps the heat source's white visible on the map
    for (const [cls, stroke, width] of [["halo", "rgba(0,0,0,0.5)", 0.065], ["mark", boxColor(o.type), 0.035]]) {
      const style = {class: cls, fill: "none", stroke: stroke, "stroke-width": width, "pointer-events": "all"};
      if ((init.marker_shapes[o.type] || "diamond") === "circle") el("circle", {r: r, ...style}, m);
      else el("polygon", {points: `0,${-r} ${r},0 0,${r} ${-r},0`, ...style}, m);
    }
    el("circle", {class: "ring", r: 0.3, fill: "none", stroke: "#111", "stroke-width": 0.03,
                  "stroke-dasharray": "0.08 0.05"}, m);
    el("title", {}, m).textContent = `truth ${o.id}: ${o.name}`;
  }
}

function pickOnMap(ev) {
  const svg = $("map"), pt = svg.createSVGPoint();
  [pt.x, pt.y] = [ev.clientX, ev.clientY];
  const p = pt.matrixTransform(svg.getScreenCTM().inverse());  // SVG coordinates: (x, -y) of the map
  let best = null, bestD = PICK_RADIUS_M;
  for (const o of init.truth) {
    const d = Math.hypot(o.x - p.x, -o.y - p.y);
    if (d <= bestD) [best, bestD] = [o, d];
  }
  if (best === null) return;
  pick("object", best.id);
  $("funnel-pane").scrollIntoView({block: "nearest"});
}

function funnelRow(r) {
  const tr = document.createElement("tr");
  tr.dataset.key = `${r.kind}:${r.id}`;
  const lost = Number(r.points_lost) || 0;
  if (lost > 0) tr.className = "lost";
  const cells = [[r.kind === "object" ? r.id : `line ${dash(r.id)}`, "num"], [r.type, "type"],
                 [r.kind === "object" ? r.name : "", ""], [lost > 0 ? lost : "0", "num points"],
                 [r.lost_to || (r.kind === "object" ? "found" : ""), "cause"]];
  for (const [v, cls] of cells) {
    const td = document.createElement("td");
    td.textContent = v;
    td.className = cls;
    if (cls === "type") td.style.borderLeftColor = boxColor(r.type);
    tr.appendChild(td);
  }
  tr.addEventListener("click", () => pick(r.kind, r.id));
  return tr;
}

function showFunnel() {
  const f = init.funnel;
  $("funnel-pane").hidden = !f;
  if (!f) return;
  $("funnel-note").hidden = !f.note;
  $("funnel-note").textContent = f.note || "";
  $("funnel-wrap").hidden = !f.rows.length;
  const body = $("funnel").querySelector("tbody");
  body.innerHTML = "";
  const objects = f.rows.filter((r) => r.kind === "object"), falses = f.rows.filter((r) => r.kind !== "object");
  for (const r of objects) body.appendChild(funnelRow(r));
  if (falses.length) {
    const tr = document.createElement("tr");
    tr.innerHTML = '<th colspan="5" class="group">charged false reports (POI file line)</th>';
    body.appendChild(tr);
    for (const r of falses) body.appendChild(funnelRow(r));
  }
  const lost = f.rows.reduce((s, r) => s + (Number(r.points_lost) || 0), 0);
  $("funnel-sum").textContent = f.rows.length ? `(${+lost.toFixed(3)} points lost; ${objects.length} objects, `
                                                + `${falses.length} false reports)` : "";
  $("funnel-detail").hidden = !f.rows.length && !(init.truth || []).length;
  $("funnel-detail").innerHTML = '<p class="hint">Pick an object (its row, or its hollow marker on the map) '
                                 + "to see its funnel.</p>";
}

function seekTo(k) {
  $("slider").value = k;
  ws.send(JSON.stringify({seek: k}));
}

function pick(kind, id) {
  const key = `${kind}:${id}`;
  for (const tr of $("funnel").querySelectorAll("tbody tr")) tr.classList.toggle("picked", tr.dataset.key === key);
  for (const g of $("truth").querySelectorAll(".truth")) {
    g.classList.toggle("picked", kind === "object" && g.dataset.id === String(id));
  }
  const row = (init.funnel ? init.funnel.rows : []).find((r) => r.kind === kind && r.id === id);
  const truth = kind === "object" ? (init.truth || []).find((o) => o.id === id) : null;
  const d = $("funnel-detail");
  d.innerHTML = "";
  const add = (tag, cls, text) => {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    d.appendChild(e);
    return e;
  };
  const type = row ? row.type : truth.type;
  const h = add("h3", "", kind === "object" ? `#${id} ${row ? row.name : truth.name}` : `false report, line ${id}`);
  h.style.borderLeftColor = boxColor(type);
  add("p", "type", truth ? `${type} · at (${truth.x}, ${truth.y}, ${truth.z}) m` : type);
  if (!row) { add("p", "hint", "no funnel for this trial"); return; }
  const lost = Number(row.points_lost) || 0;
  if (kind === "object") {
    const top = Math.max(1, ...STAGES.map(([, k]) => Number(row[k]) || 0));
    for (const [label, k, cause] of STAGES) {
      const s = add("div", row.lost_to === cause ? "stage lost" : "stage");
      s.innerHTML = '<span class="label"></span><span class="bar"><span></span></span><span class="n"></span>';
      s.querySelector(".label").textContent = label;
      s.querySelector(".bar span").style.width = `${100 * (Number(row[k]) || 0) / top}%`;
      s.querySelector(".bar span").style.background = boxColor(type);
      s.querySelector(".n").textContent = `${row[k] ?? 0} frames`;
    }
    add("p", "", `best box ${dash(row.best_px, " px")} · nearest ${dash(row.min_distance_m, " m")} · `
                 + `angle ${dash(row.min_angle_deg, "°")} · median blur ${dash(row.median_blur_px, " px")}`);
    if (row.qr_views !== null && row.qr_views !== undefined) {
      add("p", "", `QR views given to the reader ${row.qr_views}, decoded ${dash(row.qr_decoded)}`);
    }
    const p = add("p", "", `tracks ${dash(row.tracks)} · `);
    if (row.confirmed_frame === null || row.confirmed_frame === undefined) p.append("never confirmed");
    else {
      p.append("confirmed at ");
      const a = document.createElement("a");
      a.href = "#";
      a.textContent = `frame ${row.confirmed_frame + 1}`;  // 1-based, as the slider's label counts
      a.title = "show this frame";
      a.onclick = (ev) => { ev.preventDefault(); seekTo(row.confirmed_frame); };
      p.appendChild(a);
    }
  }
  add("p", lost > 0 ? "cause lost" : "cause", lost > 0 ? `${lost} points lost to ${row.lost_to}` : "no points lost");
  if (row.detail) add("p", "detail", row.detail);
}

function onFrame(m) {
  if (!init) return;
  if (m.pose && !replay && path.length < (m.path_len || path.length + 1)) path.push([m.pose[0], m.pose[1]]);
  drawPath(replay ? m.path_len : path.length);
  drawRobot(m.pose);
  drawMarkers(m.confirmed);
  showDetections(m.detections);
  showTable(m.confirmed);
  $("clock").textContent = `t ${fmtTime(m.t)} · frame ${m.k + 1} / ${init.n_frames}`;
  // points presets send total and max; a map-error preset (turtlebot) sends its headline
  $("score").textContent = !m.score ? "" : m.score.text ?? `score ${m.score.total} / ${m.score.max}`;
  if (m.images) {
    for (const key of ["camera", "thermal", "depth"]) if (m.images[key]) $(key).src = m.images[key];
  }
  if (!replay) setStatus(m.skipped ? `live · frame skipped (${m.skipped})` : "live");
  if (replay) { $("frame-label").textContent = `frame ${m.k + 1} / ${init.n_frames}`; }
}

function onInit(m) {
  init = m;
  replay = !!m.replay;
  path = m.path.slice();
  $("title").textContent = `poibench · ${m.title}`;
  drawMap();
  drawPath(path.length);
  if (replay) {
    drawTruth();
    showFunnel();
    $("replay").hidden = false;
    const slider = $("slider");
    slider.max = Math.max(m.n_frames - 1, 0);
    slider.oninput = () => {
      clearTimeout(seekTimer);
      seekTimer = setTimeout(() => seekTo(Number(slider.value)), 30);
    };
    setStatus(m.has_video ? "replay" : "replay (no camera video was recorded)");
    ws.send(JSON.stringify({seek: 0}));
  } else {
    setStatus(m.done ? "trial finished" : "live · no trial data yet, waiting for the first frame");
  }
}

const ws = new WebSocket(`ws://${location.host}/ws`);
ws.onmessage = (ev) => {
  const m = JSON.parse(ev.data);
  if (m.type === "init") onInit(m);
  else if (m.type === "frame") onFrame(m);
  else if (m.type === "empty") setStatus("no trial data yet: waiting for the trial to start");
  else if (m.type === "done") setStatus("trial finished");
};
ws.onclose = () => { if (!replay) setStatus($("status").textContent + " · disconnected"); };
