// Live top-down view of openptrack_py tracks: no build step, no dependencies.
// Connects to ws://<this host>/ws, draws the room, the sensors' fields of view, and each
// track with its id and a fading trail; during a live checkerboard session, a panel of
// its progress and a ring around each sensor that sees the board. What was last drawn is also written as JSON into
// <pre id="state"> so that tests (and curious people) can read it.
"use strict";

const TRAIL_SECONDS = 3.0;
const canvas = document.getElementById("view");
const ctx = canvas.getContext("2d");
const el = (id) => document.getElementById(id);

let scene = { room: [-5, -5, 5, 5], sensors: [], site: "-" };
let tracks = [];
const trails = new Map(); // id -> [{x, y, t}]
let frames = 0;
const arrivals = [];
let calibration = null; // the latest progress of a live checkerboard session

function colour(id) {
  const hue = (id * 137.508) % 360; // golden angle: neighbours differ
  return `hsl(${hue}, 75%, 60%)`;
}

function layout() {
  const rect = canvas.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  const width = Math.max(1, Math.round(rect.width * dpr));
  const height = Math.max(1, Math.round(rect.height * dpr));
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width; // resizing clears the canvas: only when the size changed
    canvas.height = height;
  }
  const [x0, y0, x1, y1] = scene.room;
  const pad = 40 * dpr;
  const scale = Math.min((canvas.width - 2 * pad) / (x1 - x0), (canvas.height - 2 * pad) / (y1 - y0));
  // world y points up on screen
  return {
    scale, dpr,
    px: (x) => pad + (x - x0) * scale + ((canvas.width - 2 * pad) - (x1 - x0) * scale) / 2,
    py: (y) => canvas.height - pad - (y - y0) * scale - ((canvas.height - 2 * pad) - (y1 - y0) * scale) / 2,
  };
}

function draw() {
  const v = layout();
  const [x0, y0, x1, y1] = scene.room;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  // one-metre grid and the room outline
  ctx.strokeStyle = "#222a33";
  ctx.lineWidth = 1;
  for (let x = Math.ceil(x0); x <= x1; x++) line(v.px(x), v.py(y0), v.px(x), v.py(y1));
  for (let y = Math.ceil(y0); y <= y1; y++) line(v.px(x0), v.py(y), v.px(x1), v.py(y));
  ctx.strokeStyle = "#5a6675";
  ctx.lineWidth = 2 * v.dpr;
  ctx.strokeRect(v.px(x0), v.py(y1), (x1 - x0) * v.scale, (y1 - y0) * v.scale);
  // sensors' horizontal fields of view, then the sensors on top of all of them
  for (const s of scene.sensors) {
    const yaw = (s.yaw_deg * Math.PI) / 180;
    const half = (s.hfov_deg * Math.PI) / 360;
    ctx.fillStyle = "rgba(120, 160, 220, 0.08)";
    ctx.beginPath();
    ctx.moveTo(v.px(s.x), v.py(s.y));
    for (let a = -half; a <= half + 1e-9; a += half / 12) {
      ctx.lineTo(v.px(s.x + s.range_m * Math.cos(yaw + a)), v.py(s.y + s.range_m * Math.sin(yaw + a)));
    }
    ctx.closePath();
    ctx.fill();
  }
  const seeing = new Set(calibration ? calibration.seeing : []);
  for (const s of scene.sensors) {
    if (seeing.has(s.id)) { // this sensor sees the board now
      ctx.strokeStyle = "#6fd08c";
      ctx.lineWidth = 2 * v.dpr;
      ctx.beginPath();
      ctx.arc(v.px(s.x), v.py(s.y), 10 * v.dpr, 0, 2 * Math.PI);
      ctx.stroke();
    }
    ctx.fillStyle = "#78a0dc";
    ctx.fillRect(v.px(s.x) - 4 * v.dpr, v.py(s.y) - 4 * v.dpr, 8 * v.dpr, 8 * v.dpr);
    label(s.id, v.px(s.x) + 6 * v.dpr, v.py(s.y) - 6 * v.dpr, "#78a0dc", v.dpr);
  }
  // trails, fading with age, then the people
  const now = performance.now() / 1000;
  for (const [id, trail] of trails) {
    for (let i = 1; i < trail.length; i++) {
      const alpha = Math.max(0, 1 - (now - trail[i].t) / TRAIL_SECONDS);
      ctx.strokeStyle = colour(id).replace("hsl", "hsla").replace(")", `, ${alpha * 0.8})`);
      ctx.lineWidth = 3 * v.dpr;
      line(v.px(trail[i - 1].x), v.py(trail[i - 1].y), v.px(trail[i].x), v.py(trail[i].y));
    }
  }
  for (const t of tracks) {
    ctx.fillStyle = colour(t.id);
    ctx.beginPath();
    ctx.arc(v.px(t.x), v.py(t.y), Math.max(5 * v.dpr, 0.22 * v.scale), 0, 2 * Math.PI);
    ctx.fill();
    label(trackLabel(t), v.px(t.x) + 0.25 * v.scale, v.py(t.y) - 0.25 * v.scale, "#fff", v.dpr);
  }
  el("state").textContent = JSON.stringify({
    frames,
    tracks: tracks.map((t) => ({ id: t.id, x: t.x, y: t.y, label: trackLabel(t) })),
    calibration,
  });

  function line(ax, ay, bx, by) {
    ctx.beginPath();
    ctx.moveTo(ax, ay);
    ctx.lineTo(bx, by);
    ctx.stroke();
  }
}

// a registered person's name; else the stable identity when it differs from the track id
function trackLabel(t) {
  if (t.identity) return `${t.identity} (${t.id})`;
  if (t.stable_id != null && t.stable_id !== t.id) return `${t.id} \u2192 ${t.stable_id}`;
  return String(t.id);
}

function label(text, x, y, fill, dpr) {
  ctx.fillStyle = fill;
  ctx.font = `${12 * dpr}px system-ui, sans-serif`;
  ctx.fillText(text, x, y);
}

function onTracks(msg) {
  frames += 1;
  tracks = msg.tracks;
  const now = performance.now() / 1000;
  arrivals.push(now);
  while (arrivals.length && now - arrivals[0] > 2) arrivals.shift();
  const live = new Set();
  for (const t of tracks) {
    live.add(t.id);
    const trail = trails.get(t.id) || [];
    trail.push({ x: t.x, y: t.y, t: now });
    while (trail.length && now - trail[0].t > TRAIL_SECONDS) trail.shift();
    trails.set(t.id, trail);
  }
  for (const [id, trail] of trails) {
    if (!live.has(id) && (!trail.length || now - trail[trail.length - 1].t > TRAIL_SECONDS)) {
      trails.delete(id);
    }
  }
  el("frame").textContent = String(msg.seq);
  el("count").textContent = String(tracks.length);
  el("rate").textContent = arrivals.length > 1
    ? ((arrivals.length - 1) / (arrivals[arrivals.length - 1] - arrivals[0])).toFixed(1)
    : "0.0";
  draw();
}

// the panel of a live checkerboard session: who sees the board, views, coverage, pairs
function onCalibration(msg) {
  calibration = msg;
  el("calibration").hidden = false;
  const seeing = new Set(msg.seeing);
  const body = el("calibration-sensors");
  body.replaceChildren();
  for (const id of Object.keys(msg.views).sort()) {
    const row = document.createElement("tr");
    const cells = [id, seeing.has(id) ? "seen" : "-", String(msg.views[id]),
                   `${Math.round(100 * (msg.coverage[id] || 0))} %`];
    for (const text of cells) {
      const td = document.createElement("td");
      td.textContent = text;
      row.appendChild(td);
    }
    if (seeing.has(id)) row.className = "seeing";
    body.appendChild(row);
  }
  const pairs = Object.entries(msg.pair_views).sort()
    .map(([pair, n]) => `${pair.replace("|", " + ")}: ${n}`);
  el("calibration-pairs").textContent = `views together: ${pairs.join(", ") || "none yet"}`;
  const linked = el("calibration-linked");
  linked.textContent = msg.connected ? "every sensor linked" : "not every sensor linked yet";
  linked.className = msg.connected ? "linked" : "unlinked";
  draw();
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  // a page opened with ?token=... passes it on to the stream (outputs.web.token_file)
  const token = new URLSearchParams(location.search).get("token");
  const query = token ? `?token=${encodeURIComponent(token)}` : "";
  const ws = new WebSocket(`${scheme}://${location.host}/ws${query}`);
  ws.onopen = () => { el("status").textContent = "live"; el("status").className = "ok"; };
  ws.onclose = () => {
    tracks = []; // what was drawn is stale now
    draw();
    el("status").textContent = "reconnecting";
    el("status").className = "bad";
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    const msg = JSON.parse(event.data);
    if (msg.type === "scene") {
      scene = msg;
      el("site").textContent = msg.site;
      draw();
    } else if (msg.type === "tracks") {
      onTracks(msg);
    } else if (msg.type === "calibration") {
      onCalibration(msg);
    }
  };
}

window.addEventListener("resize", draw);
connect();
