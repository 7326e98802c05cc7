// sketch.js: p5.js (global mode) view of openptrack_py's WebSocket stream.
//
// Needs p5.js loaded before it (see index.html) and opt_stream.js (global OptStream).
// Draws the room from above, one circle per person with its id and a fading trail.

/* global OptStream, createCanvas, windowWidth, windowHeight, resizeCanvas, background,
   stroke, noStroke, noFill, fill, circle, line, text, textAlign, textSize, map, width,
   height, CENTER, LEFT, TOP, strokeWeight */

let state = OptStream.createState(40);
let socket = null;
let connected = false;
let retryMs = 500;

function connect() {
  const url = OptStream.streamUrl(window.location);
  socket = new WebSocket(url);
  socket.onopen = () => {
    connected = true;
    retryMs = 500;
  };
  socket.onmessage = (event) => {
    state = OptStream.applyMessage(state, event.data);
  };
  socket.onclose = () => {
    connected = false;
    setTimeout(connect, retryMs); // the output node may not be running yet
    retryMs = Math.min(retryMs * 2, 5000);
  };
  socket.onerror = () => socket.close();
}

function setup() {
  createCanvas(windowWidth, windowHeight);
  textSize(14);
  connect();
}

function windowResized() {
  resizeCanvas(windowWidth, windowHeight);
}

// metres -> pixels, keeping the aspect ratio, y pointing up
function view() {
  const [x0, y0, x1, y1] = state.room;
  const scale = Math.min((width - 80) / (x1 - x0), (height - 80) / (y1 - y0));
  return {
    scale,
    sx: (x) => 40 + (x - x0) * scale,
    sy: (y) => height - 40 - (y - y0) * scale,
  };
}

function draw() {
  background(24);
  const v = view();
  const [x0, y0, x1, y1] = state.room;
  stroke(70);
  noFill();
  line(v.sx(x0), v.sy(y0), v.sx(x1), v.sy(y0));
  line(v.sx(x1), v.sy(y0), v.sx(x1), v.sy(y1));
  line(v.sx(x1), v.sy(y1), v.sx(x0), v.sy(y1));
  line(v.sx(x0), v.sy(y1), v.sx(x0), v.sy(y0));
  for (const s of state.sensors) {
    fill(120);
    noStroke();
    circle(v.sx(s.x), v.sy(s.y), 10);
  }
  for (const t of state.tracks) {
    const hue = (t.id * 67) % 255;
    const trail = state.trails[t.id] || [];
    strokeWeight(2);
    for (let i = 1; i < trail.length; i++) {
      stroke(hue, 160, 220, (255 * i) / trail.length);
      line(v.sx(trail[i - 1][0]), v.sy(trail[i - 1][1]), v.sx(trail[i][0]), v.sy(trail[i][1]));
    }
    noStroke();
    fill(hue, 160, 220);
    circle(v.sx(t.x), v.sy(t.y), 0.5 * v.scale);
    fill(255);
    textAlign(CENTER, CENTER);
    text(String(t.id), v.sx(t.x), v.sy(t.y));
  }
  fill(200);
  textAlign(LEFT, TOP);
  text(
    (connected ? "connected" : "connecting to " + OptStream.streamUrl(window.location)) +
      "   seq " + state.seq + "   people " + state.tracks.length +
      "   frames " + state.frames,
    10,
    10,
  );
}
