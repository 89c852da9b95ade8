// balloon view: the page served by `balloon view`. It speaks the WebSocket protocol of
// docs/viewer.md: `hello` (topology, controls, scalar fields, drag modes), `frame` (positions,
// one scalar field, statistics) and `error` from the server; control / pause / resume / reset /
// scalar / drag / release from the page.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);

// ---------------------------------------------------------------------------------------------
// Colour map: viridis sampled at 11 stops (sRGB), interpolated into a 256-entry table of linear
// colours (three.js works in linear space and converts to sRGB on output).
const VIRIDIS = [
  [0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530], [0.207, 0.372, 0.553],
  [0.164, 0.471, 0.558], [0.128, 0.567, 0.551], [0.135, 0.659, 0.518], [0.267, 0.749, 0.441],
  [0.478, 0.821, 0.318], [0.741, 0.873, 0.150], [0.993, 0.906, 0.144],
];
const LUT_SIZE = 256;
const LUT = new Float32Array(LUT_SIZE * 3);
{
  const c = new THREE.Color();
  for (let i = 0; i < LUT_SIZE; i++) {
    const x = (i / (LUT_SIZE - 1)) * (VIRIDIS.length - 1);
    const k = Math.min(Math.floor(x), VIRIDIS.length - 2);
    const f = x - k;
    const [a, b] = [VIRIDIS[k], VIRIDIS[k + 1]];
    c.setRGB(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]),
      THREE.SRGBColorSpace);
    LUT.set([c.r, c.g, c.b], i * 3);
  }
}
const NEUTRAL = new THREE.Color().setRGB(0.75, 0.75, 0.78, THREE.SRGBColorSpace);

$('legend-bar').style.background = `linear-gradient(to right, ${VIRIDIS.map(
  (c, i) => `rgb(${c.map((v) => Math.round(v * 255)).join(',')}) ${(i * 100) / (VIRIDIS.length - 1)}%`,
).join(', ')})`;

/** Short human formatting of a statistic or a legend value. */
function fmt(v) {
  if (v !== null && typeof v === 'object') return JSON.stringify(v);
  if (typeof v !== 'number') return String(v);
  if (!Number.isFinite(v)) return String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e5 || a < 1e-3)) return v.toExponential(3);
  return String(Number(v.toPrecision(4)));
}

// ---------------------------------------------------------------------------------------------
// Scene: the body (one indexed mesh, smooth normals, per-vertex colours), a headlight, the drag
// marker, and an orbit camera.
const canvas = $('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2128);
const camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
scene.add(camera);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.2));
const headlight = new THREE.DirectionalLight(0xffffff, 1.8);
headlight.position.set(0.3, 0.5, 1);
camera.add(headlight);

const material = new THREE.MeshStandardMaterial({
  vertexColors: true, side: THREE.DoubleSide, roughness: 0.55, metalness: 0.0,
});
let mesh = null; // THREE.Mesh of the body, rebuilt on every hello
let vertexCount = 0;

// Drag marker: a small sphere at the target and a line from the grabbed vertex to it.
const marker = new THREE.Group();
// Drawn last and without depth test, so the body never hides them.
const markerBall = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
  new THREE.MeshBasicMaterial({ color: 0xff8040, depthTest: false }));
const markerLine = new THREE.Line(new THREE.BufferGeometry().setAttribute('position',
  new THREE.BufferAttribute(new Float32Array(6), 3)), new THREE.LineBasicMaterial({ color: 0xff8040, depthTest: false }));
markerBall.renderOrder = markerLine.renderOrder = 1;
markerLine.frustumCulled = false; // its vertices change every frame
marker.add(markerBall, markerLine);
marker.visible = false;
scene.add(marker);

// The scene's rigid sphere (a volumetric scenario's drop-sphere, frame.sphere), if any.
const obstacle = new THREE.Mesh(new THREE.SphereGeometry(1, 32, 24),
  new THREE.MeshStandardMaterial({ color: 0x9aa3b0, roughness: 0.4, metalness: 0.1 }));
obstacle.visible = false;
scene.add(obstacle);

let needsRender = true;
let ackPending = null; // the number of a frame received and not yet acknowledged
const requestRender = () => { needsRender = true; };

// The drag listener is registered (in the capture phase) before OrbitControls adds its own, so
// a press on the body grabs it and never starts an orbit.
canvas.addEventListener('pointerdown', onPointerDown, { capture: true });
const controls = new OrbitControls(camera, canvas);
controls.addEventListener('change', requestRender);

new ResizeObserver(() => {
  const { clientWidth: w, clientHeight: h } = canvas;
  if (w === 0 || h === 0) return;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  requestRender();
}).observe(canvas);

/** Points the camera at the body's bounding sphere. */
function fitCamera() {
  if (!mesh) return;
  const s = mesh.geometry.boundingSphere;
  if (!s || !(s.radius > 0)) return;
  const dist = (s.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov) / 2)) * 1.5;
  const dir = new THREE.Vector3(0.35, 0.3, 1).normalize();
  camera.position.copy(s.center).addScaledVector(dir, dist);
  camera.near = dist / 100;
  camera.far = dist * 100;
  camera.updateProjectionMatrix();
  controls.target.copy(s.center);
  controls.update();
  markerBall.scale.setScalar(s.radius * 0.025);
  requestRender();
}
canvas.addEventListener('dblclick', fitCamera);

// ---------------------------------------------------------------------------------------------
// Connection, with polite reconnection (backing off to 10 s) when the socket closes.
let ws = null;
let retryMs = 500;
let fitPending = true; // fit the camera on the first frame after (re)connecting
const view = { frame: null, time: null, paused: false, connected: false, system: null, draggable: true, sphere: null };
window.balloonView = view; // read-only state for scripts and the end-to-end test

function setStatus(text, cls) {
  const el = $('connection');
  el.textContent = text;
  el.className = `status ${cls || ''}`;
}

function send(msg) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg));
}

function connect() {
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`;
  setStatus('connecting…');
  ws = new WebSocket(url);
  ws.onopen = () => {
    retryMs = 500;
    fitPending = true;
    view.connected = true;
    setStatus('connected', 'ok');
  };
  ws.onmessage = (ev) => {
    let msg;
    try {
      msg = JSON.parse(ev.data);
    } catch {
      showError('the server sent a message that is not JSON');
      return;
    }
    // Acknowledged after the next drawing (see animate), so the server sends the next frame
    // only when this page has drawn this one: a page slower than the server gets fewer
    // frames, never a backlog that delays the server's answers.
    if (msg.type === 'frame' && Number.isInteger(msg.frame)) ackPending = msg.frame;
    try {
      handle(msg);
    } catch (e) {
      showError(`could not use the server's ${msg.type} message: ${e.message}`);
    }
  };
  ws.onclose = () => {
    view.connected = false;
    endDrag(false);
    const s = retryMs / 1000;
    setStatus(`disconnected; reconnecting in ${s} s`, 'bad');
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 10000);
  };
}

function handle(msg) {
  switch (msg.type) {
    case 'hello': return onHello(msg);
    case 'frame': return onFrame(msg);
    case 'error': return showError(msg.message);
    case 'notice': return showNotice(msg.message);
    default: console.warn('balloon view: ignoring a message of unknown type', msg.type);
  }
}

// ---------------------------------------------------------------------------------------------
// hello: topology, controls, scalar fields, drag modes.
function onHello(h) {
  const n = h.vertex_count;
  const tris = h.triangles;
  if (!Number.isInteger(n) || n <= 0) throw new Error(`vertex_count ${n} is not a positive integer`);
  if (!Array.isArray(tris) || tris.length % 3 !== 0) throw new Error('triangles is not a list of index triples');
  const index = Uint32Array.from(tris);
  const bad = index.findIndex((i) => i >= n);
  if (bad >= 0) throw new Error(`triangle index ${index[bad]} is not below vertex_count ${n}`);

  hideError();
  view.system = h.system;
  $('system').textContent = h.system || '';
  document.title = `balloon view: ${h.system}`;

  if (mesh) {
    scene.remove(mesh);
    mesh.geometry.dispose();
  }
  const g = new THREE.BufferGeometry();
  g.setIndex(new THREE.BufferAttribute(index, 1));
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * n), 3).setUsage(THREE.DynamicDrawUsage));
  g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * n), 3).setUsage(THREE.DynamicDrawUsage));
  mesh = new THREE.Mesh(g, material);
  mesh.visible = false; // until the first frame brings positions
  scene.add(mesh);
  vertexCount = n;
  endDrag(false);

  // The colour field is this page's own choice (the server keeps it across resets); the
  // hello's `scalar` is only the default for a page that has not chosen.
  const chosen = $('scalar').value;
  fillSelect($('scalar'), h.scalar_fields || []);
  if ((h.scalar_fields || []).includes(chosen)) $('scalar').value = chosen;
  else if (h.scalar && (h.scalar_fields || []).includes(h.scalar)) $('scalar').value = h.scalar;
  fillSelect($('drag-mode'), h.drag_modes || []);
  // Every system offers its drag modes (a scenario run's drag acts on top of its anchors and
  // loads); a scenario run can be saved as a scenario file.
  view.draggable = (h.drag_modes || []).length > 0;
  $('drag-row').hidden = !view.draggable;
  $('hint').textContent = view.draggable
    ? 'drag the body to pull it · drag the background or Alt+drag to orbit · wheel to zoom'
    : 'drag or Alt+drag to orbit · wheel to zoom';
  $('save').hidden = !h.scenario;
  $('note').textContent = h.note || '';
  $('note').hidden = !h.note;
  buildControls(h.controls || []);
  requestRender();
}

function fillSelect(select, names) {
  const keep = select.value;
  select.replaceChildren(...names.map((name) => new Option(name, name)));
  if (names.includes(keep)) select.value = keep;
}

// ---------------------------------------------------------------------------------------------
// frame: positions, scalar colours, clock and statistics.
function onFrame(f) {
  if (!mesh) return;
  const g = mesh.geometry;
  const pos = g.getAttribute('position');
  if (!f.positions || f.positions.length !== 3 * vertexCount) {
    throw new Error(`${f.positions?.length} coordinates for ${vertexCount} vertices`);
  }
  pos.array.set(f.positions);
  pos.needsUpdate = true;
  g.computeVertexNormals();
  g.computeBoundingSphere();
  mesh.visible = true;

  colourBy(f.scalar);
  const sphere = f.sphere;
  obstacle.visible = !!sphere;
  if (sphere) {
    obstacle.position.set(...sphere.center);
    obstacle.scale.setScalar(sphere.radius);
  }
  view.sphere = sphere || null;

  view.frame = f.frame;
  view.time = f.time;
  view.paused = !!f.paused;
  $('frame').textContent = String(f.frame);
  $('time').textContent = `${Number(f.time).toFixed(4)} s${f.paused ? ' (paused)' : ''}`;
  $('pause').textContent = f.paused ? 'resume' : 'pause';
  showStats(f.stats || {});
  if (fitPending) {
    fitPending = false;
    fitCamera();
  }
  requestRender();
}

function colourBy(scalar) {
  const col = mesh.geometry.getAttribute('color');
  const c = col.array;
  const legend = $('legend');
  if (!scalar || !scalar.values || scalar.values.length !== vertexCount) {
    for (let i = 0; i < vertexCount; i++) c.set([NEUTRAL.r, NEUTRAL.g, NEUTRAL.b], 3 * i);
    legend.hidden = true;
  } else {
    const { values, min, max } = scalar;
    const span = max > min ? max - min : 0;
    for (let i = 0; i < vertexCount; i++) {
      const v = values[i];
      // Undefined values (NaN, sent as null: e.g. the stretch of a zero-area soup triangle).
      if (v === null || !Number.isFinite(v)) {
        c.set([NEUTRAL.r, NEUTRAL.g, NEUTRAL.b], 3 * i);
        continue;
      }
      const t = span > 0 ? (v - min) / span : 0.5;
      const k = 3 * Math.round(Math.min(Math.max(t, 0), 1) * (LUT_SIZE - 1));
      c[3 * i] = LUT[k];
      c[3 * i + 1] = LUT[k + 1];
      c[3 * i + 2] = LUT[k + 2];
    }
    legend.hidden = false;
    $('legend-name').textContent = scalar.name;
    $('legend-min').textContent = fmt(min);
    $('legend-mid').textContent = fmt((min + max) / 2);
    $('legend-max').textContent = fmt(max);
    const select = $('scalar');
    if (document.activeElement !== select && select.value !== scalar.name) select.value = scalar.name;
  }
  col.needsUpdate = true;
}

function showStats(stats) {
  const rows = [];
  for (const [k, v] of Object.entries(stats)) {
    rows.push(Object.assign(document.createElement('dt'), { textContent: k.replaceAll('_', ' ') }));
    rows.push(Object.assign(document.createElement('dd'), { textContent: fmt(v) }));
  }
  $('stats').replaceChildren(...rows);
}

// ---------------------------------------------------------------------------------------------
// Errors from the server (rejected messages, simulation failures) and from the page itself.
// An error stays visible while the simulation is paused (a failed simulation pauses itself until
// reset), otherwise for 12 s; a click dismisses it, a new hello (reset) clears it.
let errorTimer = null;
function hideError() {
  clearTimeout(errorTimer);
  $('error').hidden = true;
}
function showError(message) {
  const el = $('error');
  el.textContent = message;
  el.hidden = false;
  clearTimeout(errorTimer);
  const expire = () => { if (view.paused) errorTimer = setTimeout(expire, 2000); else el.hidden = true; };
  errorTimer = setTimeout(expire, 12000);
  syncControlValues(); // a rejected control keeps the server's value: show that one again
}
$('error').addEventListener('click', hideError);

// A notice: something the server did on its own (a drag that crushed the wall, undone). The
// server has dropped the drag, so the page ends its own; the next press starts a new one.
let noticeTimer = null;
function showNotice(message) {
  const el = $('notice');
  el.textContent = message;
  el.hidden = false;
  endDrag(false);
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { el.hidden = true; }, 15000);
}
$('notice').addEventListener('click', () => { clearTimeout(noticeTimer); $('notice').hidden = true; });

// ---------------------------------------------------------------------------------------------
// Controls generated from hello's list: numbers (slider + box), choices (select), booleans.
const widgets = new Map(); // control name -> function(value) that shows a value

function buildControls(list) {
  widgets.clear();
  $('controls').replaceChildren(...list.map(controlWidget));
}

function controlWidget(c) {
  const div = document.createElement('div');
  div.className = 'control';
  div.dataset.name = c.name;
  const label = document.createElement('label');
  label.className = 'label';
  label.htmlFor = `control-${c.name}`;
  label.textContent = c.label || c.name;
  if (c.resets) {
    const r = document.createElement('span');
    r.className = 'resets';
    r.textContent = 'restarts';
    r.title = 'changing this rebuilds the simulation';
    label.append(r);
  }
  const inputs = document.createElement('div');
  inputs.className = 'inputs';
  div.append(label, inputs);
  const set = (value) => send({ type: 'control', name: c.name, value });

  if (c.kind === 'number') {
    const box = Object.assign(document.createElement('input'), {
      type: 'number', id: `control-${c.name}`, step: c.step ?? 'any',
    });
    const bounded = Number.isFinite(c.min) && Number.isFinite(c.max);
    let slider = null;
    if (Number.isFinite(c.min)) box.min = c.min;
    if (Number.isFinite(c.max)) box.max = c.max;
    if (bounded) {
      slider = Object.assign(document.createElement('input'), {
        type: 'range', id: `control-${c.name}-range`, min: c.min, max: c.max,
        step: c.step ?? 'any',
      });
      slider.addEventListener('input', () => { box.value = slider.value; });
      slider.addEventListener('change', () => set(Number(slider.value)));
      inputs.append(slider);
    }
    box.addEventListener('change', () => {
      const v = Number(box.value);
      if (box.value.trim() === '' || !Number.isFinite(v)) {
        showError(`${c.label || c.name}: "${box.value}" is not a number`);
        return;
      }
      if (slider) slider.value = v;
      set(v);
    });
    inputs.append(box);
    widgets.set(c.name, (v) => { box.value = v; if (slider) slider.value = v; });
  } else if (c.kind === 'choice') {
    const select = document.createElement('select');
    select.id = `control-${c.name}`;
    fillSelect(select, c.choices || []);
    select.addEventListener('change', () => set(select.value));
    inputs.append(select);
    widgets.set(c.name, (v) => { select.value = v; });
  } else if (c.kind === 'bool') {
    const box = Object.assign(document.createElement('input'), { type: 'checkbox', id: `control-${c.name}` });
    box.addEventListener('change', () => set(box.checked));
    inputs.append(box);
    widgets.set(c.name, (v) => { box.checked = !!v; });
  } else {
    inputs.textContent = `(unsupported kind ${c.kind})`;
  }
  if (c.unit) inputs.append(Object.assign(document.createElement('span'), { className: 'unit', textContent: c.unit }));
  widgets.get(c.name)?.(c.value);
  return div;
}

/** Shows the server's current control values (GET /api/state), e.g. after a rejected value. */
async function syncControlValues() {
  try {
    const res = await fetch('api/state');
    if (!res.ok) return;
    const state = await res.json();
    for (const [name, value] of Object.entries(state.controls || {})) {
      if (document.activeElement?.id !== `control-${name}`) widgets.get(name)?.(value);
    }
  } catch {
    // the socket's own reconnection reports a server that went away
  }
}

$('pause').addEventListener('click', () => send({ type: view.paused ? 'resume' : 'pause' }));
$('reset').addEventListener('click', () => send({ type: 'reset' }));
$('scalar').addEventListener('change', (ev) => send({ type: 'scalar', name: ev.target.value }));

// ---------------------------------------------------------------------------------------------
// Mouse drag: a press on the body grabs the nearest vertex of the hit triangle; moving the mouse
// pulls it towards the point under the cursor on the plane through the grabbed point facing the
// camera; releasing the button drops it. A press off the body (or with Alt) orbits instead.
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let drag = null; // { pointerId, vertex, plane, target, dirty }
let hover = null; // last pointer event over the canvas, for the hover cursor

function castFrom(ev) {
  const r = canvas.getBoundingClientRect();
  pointer.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  return mesh && mesh.visible ? raycaster.intersectObject(mesh, false)[0] ?? null : null;
}

function vertexPosition(i, out = new THREE.Vector3()) {
  return out.fromBufferAttribute(mesh.geometry.getAttribute('position'), i);
}

function onPointerDown(ev) {
  if (ev.button !== 0 || ev.altKey || !view.connected || !view.draggable) return; // leave it to OrbitControls
  const hit = castFrom(ev);
  if (!hit) return;
  let best = -1;
  let bestD = Infinity;
  for (const i of [hit.face.a, hit.face.b, hit.face.c]) {
    const d = vertexPosition(i).distanceToSquared(hit.point);
    if (d < bestD) [best, bestD] = [i, d];
  }
  const p = vertexPosition(best);
  const normal = camera.getWorldDirection(new THREE.Vector3());
  drag = {
    pointerId: ev.pointerId, vertex: best, dirty: true, target: p.clone(),
    plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, p),
  };
  canvas.setPointerCapture(ev.pointerId);
  canvas.classList.add('dragging');
  ev.stopImmediatePropagation();
  ev.preventDefault();
}

canvas.addEventListener('pointermove', (ev) => {
  hover = ev;
  if (!drag || ev.pointerId !== drag.pointerId) return;
  const r = canvas.getBoundingClientRect();
  pointer.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  if (raycaster.ray.intersectPlane(drag.plane, drag.target)) drag.dirty = true;
});

function endDrag(sendRelease) {
  if (!drag) return;
  if (sendRelease) send({ type: 'release' });
  if (canvas.hasPointerCapture(drag.pointerId)) canvas.releasePointerCapture(drag.pointerId);
  drag = null;
  canvas.classList.remove('dragging');
  marker.visible = false;
  requestRender();
}
canvas.addEventListener('pointerup', (ev) => { if (drag && ev.pointerId === drag.pointerId) endDrag(true); });
canvas.addEventListener('pointercancel', () => endDrag(true));
canvas.addEventListener('pointerleave', () => { hover = null; });

// ---------------------------------------------------------------------------------------------
// Animation loop: sends at most one drag message per animation frame, updates the hover cursor
// and the drag marker, and renders only when something changed.
function animate() {
  if (drag && drag.dirty) {
    drag.dirty = false;
    send({ type: 'drag', vertex: drag.vertex, target: drag.target.toArray(), mode: $('drag-mode').value || 'grab' });
  }
  if (drag) {
    const p = vertexPosition(drag.vertex);
    markerBall.position.copy(drag.target);
    const line = markerLine.geometry.getAttribute('position');
    line.setXYZ(0, p.x, p.y, p.z);
    line.setXYZ(1, drag.target.x, drag.target.y, drag.target.z);
    line.needsUpdate = true;
    marker.visible = true;
    needsRender = true;
  } else if (hover) {
    canvas.classList.toggle('over-body', !hover.altKey && castFrom(hover) !== null);
    hover = null;
  }
  if (needsRender) {
    needsRender = false;
    renderer.render(scene, camera);
  }
  if (ackPending !== null) {
    send({ type: 'ack', frame: ackPending });
    ackPending = null;
  }
}
renderer.setAnimationLoop(animate);
connect();
