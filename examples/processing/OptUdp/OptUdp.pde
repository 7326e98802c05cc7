// OptUdp: draws the people tracked by openptrack_py (or OpenPTrack) as circles.
//
// Listens for the UDP JSON on port 21234 with the "UDP" library by Stephane Cousot
// (hypermedia.net; Sketch > Import Library > Manage Libraries > "UDP").
// Reads both root keys ("people_tracks" = opt-v2, "tracks" = opt-v1), with or without
// the trailing NUL byte, and ignores heartbeats ("alive_IDs") and anything unreadable
// instead of stopping. Coordinates are metres on the floor; the view shows the area
// given by ROOM (x0, y0, x1, y1), y pointing up.

import hypermedia.net.*;

final int PORT = 21234;
final float[] ROOM = { -1, -1, 9, 7 };  // metres: the demo room is 8 x 6 m from (0, 0)

UDP udp;
// written by the UDP thread, read by draw(): always replaced as a whole
volatile ArrayList<Person> people = new ArrayList<Person>();
volatile int frames = 0;
volatile int heartbeats = 0;
volatile int unreadable = 0;
volatile int aliveCount = 0;
volatile long lastSeq = -1;

class Person {
  int id;
  float x, y, height, age, confidence;
  Person(int id, float x, float y, float height, float age, float confidence) {
    this.id = id;
    this.x = x;
    this.y = y;
    this.height = height;
    this.age = age;
    this.confidence = confidence;
  }
}

void setup() {
  size(900, 680);
  textSize(14);
  udp = new UDP(this, PORT);
  udp.listen(true);
}

// Called by the UDP library for every datagram. Never throws: a bad datagram is
// counted and skipped.
void receive(byte[] data, String ip, int port) {
  try {
    handleDatagram(data);
  }
  catch (RuntimeException e) {
    unreadable++;
  }
}

void handleDatagram(byte[] data) {
  // Cut at the first NUL: openptrack_py may send one trailing NUL (OpenPTrack always
  // did, and old versions padded with zeros) or none.
  int n = 0;
  while (n < data.length && data[n] != 0) n++;
  String text = new String(data, 0, n, java.nio.charset.StandardCharsets.UTF_8).trim();
  JSONObject json = parseJSONObject(text);  // throws (or gives null) if not JSON
  if (json == null) {
    unreadable++;
    return;
  }
  if (json.hasKey("alive_IDs")) {  // heartbeat: which ids the tracker still holds
    JSONArray alive = json.getJSONArray("alive_IDs");
    aliveCount = alive == null ? 0 : alive.size();
    heartbeats++;
    return;
  }
  JSONArray tracks = null;
  if (json.hasKey("people_tracks")) tracks = json.getJSONArray("people_tracks");
  else if (json.hasKey("tracks")) tracks = json.getJSONArray("tracks");
  if (tracks == null) return;  // some other message kind: not for us
  ArrayList<Person> next = new ArrayList<Person>();
  for (int i = 0; i < tracks.size(); i++) {
    JSONObject t = tracks.getJSONObject(i);
    next.add(new Person(t.getInt("id"), t.getFloat("x"), t.getFloat("y"),
      t.getFloat("height", 0), t.getFloat("age", 0), t.getFloat("confidence", 0)));
  }
  JSONObject header = json.getJSONObject("header");
  if (header != null && header.hasKey("seq")) lastSeq = header.getLong("seq");
  people = next;  // replaced as a whole: draw() never sees half a frame
  frames++;
}

float toScreenX(float x) {
  return map(x, ROOM[0], ROOM[2], 40, width - 40);
}

float toScreenY(float y) {
  return map(y, ROOM[1], ROOM[3], height - 40, 40);
}

void draw() {
  background(24);
  // floor grid, one line per metre
  stroke(60);
  for (float gx = ceil(ROOM[0]); gx <= ROOM[2]; gx += 1) line(toScreenX(gx), toScreenY(ROOM[1]), toScreenX(gx), toScreenY(ROOM[3]));
  for (float gy = ceil(ROOM[1]); gy <= ROOM[3]; gy += 1) line(toScreenX(ROOM[0]), toScreenY(gy), toScreenX(ROOM[2]), toScreenY(gy));

  ArrayList<Person> now = people;  // one consistent frame
  float pixelsPerMetre = (width - 80) / (ROOM[2] - ROOM[0]);
  for (Person p : now) {
    float sx = toScreenX(p.x);
    float sy = toScreenY(p.y);
    noStroke();
    fill((p.id * 67) % 255, 160, 220, 200);
    ellipse(sx, sy, 0.5 * pixelsPerMetre, 0.5 * pixelsPerMetre);
    fill(255);
    textAlign(CENTER, CENTER);
    text(p.id, sx, sy);
    textAlign(LEFT, TOP);
    text(nf(p.height, 1, 2) + " m", sx + 0.3 * pixelsPerMetre, sy);
  }
  fill(200);
  textAlign(LEFT, TOP);
  text("port " + PORT + "   seq " + lastSeq + "   people " + now.size() + "   alive " + aliveCount
    + "   frames " + frames + "   heartbeats " + heartbeats + "   unreadable " + unreadable, 10, 10);
}
