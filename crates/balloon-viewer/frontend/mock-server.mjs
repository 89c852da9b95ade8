// A stand-in for `balloon view` for working on the page without the Rust server: serves ../web
// and speaks the protocol of docs/viewer.md with a toy "simulation" (an icosphere that breathes
// with the pressure control and follows drags with a smooth fall-off). Dependency-free: node's
// http plus a minimal WebSocket (RFC 6455) for small text messages.
//
//   node mock-server.mjs [SYSTEM] [--port N]     prints "balloon view: serving SYSTEM at URL"
//   node e2e.mjs --mock                          runs the end-to-end test against it

import { createServer } from 'node:http';
import { createHash } from 'node:crypto';
import { readFileSync, existsSync } from 'node:fs';
import { dirname, join, normalize, extname } from 'node:path';
import { fileURLToPath } from 'node:url';

const web = join(dirname(fileURLToPath(import.meta.url)), '..', 'web');
const args = process.argv.slice(2);
const system = args.find((a) => !a.startsWith('--')) || 'shell';
const port = Number(args[args.indexOf('--port') + 1]) || 0;

// --- toy body: icosphere, 2 subdivisions --------------------------------------------------------
function icosphere(levels) {
  const t = (1 + Math.sqrt(5)) / 2;
  let v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
    [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]];
  let f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
    [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
    [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]];
  for (let l = 0; l < levels; l++) {
    const mid = new Map();
    const m = (a, b) => {
      const k = a < b ? `${a},${b}` : `${b},${a}`;
      if (!mid.has(k)) { mid.set(k, v.length); v.push(v[a].map((x, i) => (x + v[b][i]) / 2)); }
      return mid.get(k);
    };
    f = f.flatMap(([a, b, c]) => { const [ab, bc, ca] = [m(a, b), m(b, c), m(c, a)]; return [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]; });
  }
  return { dirs: v.map((p) => { const n = Math.hypot(...p); return p.map((x) => x / n); }), tris: f.flat() };
}
const body = icosphere(2);
const n = body.dirs.length;
const controls = [
  { name: 'pressure', label: 'gauge pressure', kind: 'number', value: 2, min: 0, max: 10, step: 0.1, choices: [], unit: 'kPa', resets: false },
  { name: 'thickness', label: 'thickness', kind: 'number', value: 0.5, min: 0.05, max: 5, step: 0.05, choices: [], unit: 'mm', resets: true },
  { name: 'material', label: 'material', kind: 'choice', value: 'neo-hookean', min: null, max: null, step: null, choices: ['neo-hookean', 'stvk'], unit: '', resets: true },
  { name: 'gravity', label: 'gravity', kind: 'bool', value: false, min: null, max: null, step: null, choices: [], unit: '', resets: false },
];
const sim = { frame: 0, time: 0, paused: false, scalar: 'thickness', drag: null, offsets: new Float64Array(3 * n), error: null };
const values = Object.fromEntries(controls.map((c) => [c.name, c.value]));
function positions() {
  const r = 0.1 * (1 + 0.05 * values.pressure * (1 - Math.exp(-sim.time)));
  return body.dirs.flatMap((d, i) => d.map((x, k) => r * x + sim.offsets[3 * i + k] - (values.gravity ? 0.01 : 0) * (k === 1)));
}
function step(dt) {
  sim.frame += 1;
  sim.time += dt;
  const p = positions();
  const d = sim.drag;
  for (let i = 0; i < n; i++) {
    let w = 0;
    if (d) {
      const dd = body.dirs[i].reduce((s, x, k) => s + (x - body.dirs[d.vertex][k]) ** 2, 0);
      w = Math.exp(-dd / 0.1);
    }
    for (let k = 0; k < 3; k++) {
      const pull = d ? w * (d.target[k] - p[3 * d.vertex + k]) : 0;
      sim.offsets[3 * i + k] += 0.2 * pull - 0.05 * sim.offsets[3 * i + k];
    }
  }
}
function frameMsg() {
  const vals = body.dirs.map((d) => (sim.scalar === 'thickness' ? values.thickness * (1 + 0.2 * d[1]) : 1 + 0.1 * d[0]));
  return {
    type: 'frame', frame: sim.frame, time: sim.time, paused: sim.paused, positions: positions(),
    scalar: { name: sim.scalar, values: vals, min: Math.min(...vals), max: Math.max(...vals) },
    stats: { gauge_pressure: values.pressure * 1000, gas_volume: 4.19e-3 },
  };
}
const hello = () => ({ type: 'hello', system, triangles: body.tris, vertex_count: n,
  controls: controls.map((c) => ({ ...c, value: values[c.name] })), scalar_fields: ['thickness', 'stretch'], drag_modes: ['grab', 'pinch'] });

function apply(msg, reply) {
  const err = (message) => reply({ type: 'error', message });
  switch (msg.type) {
    case 'control': {
      const c = controls.find((x) => x.name === msg.name);
      if (!c) return err(`unknown control "${msg.name}"`);
      if (c.kind === 'number' && !(typeof msg.value === 'number' && msg.value >= c.min && msg.value <= c.max)) {
        return err(`${c.name}: ${msg.value} is outside [${c.min}, ${c.max}] ${c.unit}`);
      }
      values[c.name] = msg.value;
      if (c.resets) { sim.frame = 0; sim.time = 0; sim.offsets.fill(0); reply(hello()); }
      return;
    }
    case 'pause': sim.paused = true; return;
    case 'resume': sim.paused = false; return;
    case 'reset': sim.frame = 0; sim.time = 0; sim.offsets.fill(0); sim.drag = null; reply(hello()); return;
    case 'scalar': sim.scalar = msg.name; return;
    case 'drag': sim.drag = { vertex: msg.vertex, target: msg.target, mode: msg.mode }; return;
    case 'release': sim.drag = null; return;
    case 'ack': return; // the mock sends every frame
    default: err(`unknown message type "${msg.type}"`);
  }
}

// --- minimal WebSocket ----------------------------------------------------------------------------
function wsFrame(text) {
  const data = Buffer.from(text);
  const len = data.length;
  const head = len < 126 ? Buffer.from([0x81, len])
    : len < 65536 ? Buffer.from([0x81, 126, len >> 8, len & 255])
      : Buffer.concat([Buffer.from([0x81, 127]), (() => { const b = Buffer.alloc(8); b.writeBigUInt64BE(BigInt(len)); return b; })()]);
  return Buffer.concat([head, data]);
}
function onUpgrade(req, socket) {
  const accept = createHash('sha1').update(`${req.headers['sec-websocket-key']}258EAFA5-E914-47DA-95CA-C5AB0DC85B11`).digest('base64');
  socket.write(`HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: ${accept}\r\n\r\n`);
  const reply = (m) => socket.writable && socket.write(wsFrame(JSON.stringify(m)));
  reply(hello());
  const timer = setInterval(() => { if (!sim.paused) step(1 / 30); reply(frameMsg()); }, 33);
  let buf = Buffer.alloc(0);
  socket.on('data', (chunk) => {
    buf = Buffer.concat([buf, chunk]);
    while (buf.length >= 2) {
      const op = buf[0] & 15;
      let len = buf[1] & 127;
      let off = 2;
      if (len === 126) { len = buf.readUInt16BE(2); off = 4; }
      if (len === 127) { len = Number(buf.readBigUInt64BE(2)); off = 10; }
      if (buf.length < off + 4 + len) return;
      const mask = buf.subarray(off, off + 4);
      const data = Buffer.from(buf.subarray(off + 4, off + 4 + len).map((b, i) => b ^ mask[i % 4]));
      buf = buf.subarray(off + 4 + len);
      if (op === 8) { socket.end(Buffer.from([0x88, 0])); return; }
      if (op !== 1) continue;
      let msg;
      try { msg = JSON.parse(data.toString()); } catch { reply({ type: 'error', message: 'malformed JSON' }); continue; }
      apply(msg, reply);
    }
  });
  socket.on('close', () => clearInterval(timer));
  socket.on('error', () => clearInterval(timer));
}

// --- HTTP -------------------------------------------------------------------------------------------
const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.txt': 'text/plain' };
const server = createServer((req, res) => {
  const url = new URL(req.url, 'http://x');
  if (url.pathname === '/api/state') {
    const p = positions();
    const i = Number(url.searchParams.get('vertex'));
    const axis = (k) => p.filter((_, j) => j % 3 === k);
    const state = { system, frame: sim.frame, time: sim.time, paused: sim.paused, vertex_count: n, controls: values,
      centroid: [0, 1, 2].map((k) => axis(k).reduce((a, b) => a + b, 0) / n),
      bbox_min: [0, 1, 2].map((k) => Math.min(...axis(k))), bbox_max: [0, 1, 2].map((k) => Math.max(...axis(k))),
      drag: sim.drag && { ...sim.drag, position: p.slice(3 * sim.drag.vertex, 3 * sim.drag.vertex + 3) }, last_error: null };
    if (url.searchParams.has('vertex')) state.vertex = { index: i, position: p.slice(3 * i, 3 * i + 3) };
    res.writeHead(200, { 'content-type': 'application/json' });
    res.end(JSON.stringify(state));
    return;
  }
  const file = normalize(join(web, url.pathname === '/' ? 'index.html' : url.pathname));
  if (!file.startsWith(web) || !existsSync(file)) { res.writeHead(404); res.end('not found'); return; }
  res.writeHead(200, { 'content-type': TYPES[extname(file)] || 'application/octet-stream' });
  res.end(readFileSync(file));
});
server.on('upgrade', onUpgrade);
server.listen(port, '127.0.0.1', () => {
  console.log(`balloon view: serving ${system} at http://127.0.0.1:${server.address().port}/`);
});
