// opt_stream.js: turns the messages of openptrack_py's WebSocket stream into state.
//
// No dependency and no I/O: the sketch hands every message text to applyMessage(), and
// draws from the state. Works as a plain <script> in a browser (global `OptStream`)
// and as a CommonJS module in Node (`require("./opt_stream.js")`).
//
// The stream (ws://host:8080/ws, the output node's `web` sink) sends JSON text:
//   once:        {"type": "scene", "site", "room": [x0, y0, x1, y1], "sensors": [...]}
//   every frame: {"type": "tracks", "seq", "stamp", "tracks": [{"id", "x", "y", "z",
//                 "height", "vx", "vy", "age", "confidence", "visibility", "confirmed"}],
//                 "alive_ids", "max_id"}
(function (root, factory) {
  const api = factory();
  if (typeof module === "object" && module.exports) module.exports = api;
  else root.OptStream = api;
})(typeof self !== "undefined" ? self : this, function () {
  "use strict";

  const TRACK_FIELDS = ["x", "y", "z", "height", "vx", "vy", "age", "confidence"];

  // A fresh state. `trailLength` positions are kept per person for drawing trails.
  function createState(trailLength) {
    return {
      site: null,
      room: [-5, -5, 5, 5],
      sensors: [],
      seq: -1,
      stamp: null,
      tracks: [],
      aliveIds: [],
      maxId: 0,
      frames: 0,
      errors: 0,
      trails: {},
      trailLength: trailLength === undefined ? 30 : trailLength,
    };
  }

  function isNumber(v) {
    return typeof v === "number" && isFinite(v);
  }

  function cleanTrack(t) {
    if (t === null || typeof t !== "object" || !Number.isInteger(t.id)) return null;
    const out = { id: t.id, visibility: Number.isInteger(t.visibility) ? t.visibility : 0 };
    for (const key of TRACK_FIELDS) {
      if (isNumber(t[key])) out[key] = t[key];
      else if (key === "x" || key === "y") return null; // no position: not drawable
      else out[key] = 0;
    }
    return out;
  }

  // Apply one message (the text of a WebSocket message event) to `state`; returns the
  // state. Unreadable or unknown messages only increment `state.errors`.
  function applyMessage(state, text) {
    let msg;
    try {
      msg = JSON.parse(text);
    } catch (e) {
      state.errors += 1;
      return state;
    }
    if (msg === null || typeof msg !== "object") {
      state.errors += 1;
      return state;
    }
    if (msg.type === "scene") {
      if (Array.isArray(msg.room) && msg.room.length === 4 && msg.room.every(isNumber)) {
        state.room = msg.room.slice();
      }
      state.site = typeof msg.site === "string" ? msg.site : null;
      state.sensors = Array.isArray(msg.sensors) ? msg.sensors : [];
      return state;
    }
    if (msg.type !== "tracks" || !Array.isArray(msg.tracks)) {
      state.errors += 1;
      return state;
    }
    const tracks = msg.tracks.map(cleanTrack).filter((t) => t !== null);
    tracks.sort((a, b) => a.id - b.id);
    const trails = {};
    for (const t of tracks) {
      const trail = (state.trails[t.id] || []).concat([[t.x, t.y]]);
      trails[t.id] = trail.slice(Math.max(0, trail.length - state.trailLength));
    }
    state.trails = trails; // people who left lose their trail
    state.tracks = tracks;
    state.seq = Number.isInteger(msg.seq) ? msg.seq : state.seq;
    state.stamp = isNumber(msg.stamp) ? msg.stamp : state.stamp;
    state.aliveIds = Array.isArray(msg.alive_ids) ? msg.alive_ids.filter(Number.isInteger) : [];
    state.maxId = Number.isInteger(msg.max_id) ? msg.max_id : state.maxId;
    state.frames += 1;
    return state;
  }

  // The stream's URL: `?ws=ws://host:port/ws` in the page address wins, otherwise the
  // page's own host (or localhost) on port 8080.
  function streamUrl(location) {
    const search = (location && location.search) || "";
    const match = /[?&]ws=([^&]+)/.exec(search);
    if (match) return decodeURIComponent(match[1]);
    const host = (location && location.hostname) || "localhost";
    return "ws://" + host + ":8080/ws";
  }

  return { createState, applyMessage, streamUrl };
});
