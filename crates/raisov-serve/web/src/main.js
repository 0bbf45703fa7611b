// The page of `raisov serve`: draws the organ's surface from binary frames, sends grasps,
// moves, pins, cuts and switches (protocol: crates/raisov-serve/src/protocol.rs).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const STAT = { simFps: 0, residual: 1, cycles: 2, frameMs: 3, inputLag: 4, force: 5, grasp: 8,
  scalarMax: 11, method: 12, appliedSeq: 13, holder: 14, grasped: 15, rejectedTries: 16, rejectedSteps: 17 };
const NSTATS = 18;
const HEADER = 16 + 4 * NSTATS;
// Frame flags.
const FLAG = { held: 1, stress: 2, rest: 4, stuck: 8, diverged: 16 };
const $ = (id) => document.getElementById(id);

// Viridis (polynomial fit of matplotlib's map), 256 entries.
const VIRIDIS = (() => {
  const c = [[0.2777273272234177, 0.005407344544966578, 0.3340998053353061],
    [0.1050930431085774, 1.404613529898575, 1.384590162594685],
    [-0.3308618287255563, 0.214847559468213, 0.09509516302823659],
    [-4.634230498983486, -5.799100973351585, -19.33244095627987],
    [6.228269936347081, 14.17993336680509, 56.69055260068105],
    [4.776384997670288, -13.74514537774601, -65.35303263337234],
    [-5.435455855934631, 4.645852612178535, 26.3124352495832]];
  const lut = new Float32Array(256 * 3);
  for (let i = 0; i < 256; i++) {
    const t = i / 255;
    for (let k = 0; k < 3; k++) {
      let v = c[6][k];
      for (let j = 5; j >= 0; j--) v = v * t + c[j][k];
      lut[3 * i + k] = Math.min(1, Math.max(0, v));
    }
  }
  return lut;
})();

// The page's state; `window.raisovState` lets a test read it.
const state = {
  webgl: false, client: null, holder: null, topology: null, frames: 0, firstPositions: null,
  positions: null, forceN: 0, force: [0, 0, 0], bytesPerFrame: 0, errors: [], simFps: 0,
  displayFps: 0, latencyMs: null, latencySamples: [], serverLagMs: null, residuals: [], method: 0, stress: false,
  resting: false, stuck: false, diverged: false, budget: null, maxFps: 0, pins: [],
  legendStress: null, legendMax: 0, budgetUsed: null,
  // Topology messages received (the first, then one after each cut, switch or reset), the
  // scalpel mode, cut messages sent, and the server's count of cuts that split the body.
  topologies: 0, scalpel: false, cutsSent: 0, cutsAnswered: 0, cuts: 0, lastCut: null,
};
window.raisovState = state;

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
state.webgl = !!renderer.getContext();
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
$('view').appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d1f24);
const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 0.001, 100);
camera.up.set(0, 0, 1);
scene.add(new THREE.HemisphereLight(0xffffff, 0x303040, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
scene.add(sun);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;

const geometry = new THREE.BufferGeometry();
const material = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
const mesh = new THREE.Mesh(geometry, material);
scene.add(mesh);
const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0.01, 0xff4040);
arrow.visible = false;
// Drawn over the organ: the arrow starts inside the tissue's surface.
for (const m of [arrow.line.material, arrow.cone.material]) { m.depthTest = false; m.transparent = true; }
arrow.renderOrder = 10;
scene.add(arrow);
const grabMarker = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
  new THREE.MeshBasicMaterial({ color: 0xff4040 }));
grabMarker.visible = false;
scene.add(grabMarker);
let diag = 0.1;
let framed = false;
// The pins: a translucent sphere of the pin's radius and a small solid marker at its point.
const pinGroup = new THREE.Group();
scene.add(pinGroup);
const pinMaterial = new THREE.MeshBasicMaterial({ color: 0x4cc9f0, transparent: true, opacity: 0.35, depthWrite: false });
const pinCore = new THREE.MeshBasicMaterial({ color: 0x4cc9f0 });
function drawPins() {
  pinGroup.clear();
  for (const [x, y, z, r] of state.pins) {
    const ball = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12), pinMaterial);
    ball.position.set(x, y, z);
    ball.scale.setScalar(Math.max(r, diag * 0.004));
    const core = new THREE.Mesh(new THREE.SphereGeometry(1, 12, 8), pinCore);
    core.position.set(x, y, z);
    core.scale.setScalar(diag * 0.004);
    pinGroup.add(ball, core);
  }
  $('pins').textContent = `${state.pins.length}`;
}

window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

// --- the connection ---
let seq = 1;
const sentAt = new Map();
const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
ws.binaryType = 'arraybuffer';
function send(kind, floats = [], u32 = null) {
  if (ws.readyState !== WebSocket.OPEN) return 0;
  const n = 8 + 4 * (u32 === null ? floats.length : 1);
  const b = new DataView(new ArrayBuffer(n));
  b.setUint8(0, kind);
  // The counter wraps at 2^32 (the server compares modulo 2^32).
  const s = seq;
  seq = (seq + 1) >>> 0;
  b.setUint32(4, s, true);
  if (u32 !== null) b.setUint32(8, u32, true);
  else floats.forEach((x, i) => b.setFloat32(8 + 4 * i, x, true));
  ws.send(b.buffer);
  return s;
}
ws.onopen = () => { $('status').textContent = 'connected'; };
ws.onclose = () => { $('status').textContent = 'disconnected: reload the page'; };
ws.onmessage = (ev) => {
  if (typeof ev.data === 'string') return onText(JSON.parse(ev.data));
  const dv = new DataView(ev.data);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic === 'RSVT') onTopology(dv);
  else if (magic === 'RSVF') onFrame(dv, ev.data.byteLength);
};

// Errors stay listed, newest first, each with its age, for 30 s (the newest five).
const errorLog = [];
function showError(m) {
  state.errors.push(m);
  if (state.errors.length > 20) state.errors.shift();
  errorLog.unshift({ m, at: performance.now() });
  if (errorLog.length > 5) errorLog.pop();
  drawErrors();
}
function drawErrors() {
  const now = performance.now();
  while (errorLog.length && now - errorLog[errorLog.length - 1].at > 30000) errorLog.pop();
  const box = $('errors');
  box.replaceChildren(...errorLog.map(({ m, at }) => {
    const d = document.createElement('div');
    const age = document.createElement('span');
    age.className = 'age';
    age.textContent = `${Math.round((now - at) / 1000)} s ago: `;
    d.append(age, document.createTextNode(m));
    return d;
  }));
}
setInterval(drawErrors, 1000);

function onText(m) {
  if (m.type === 'hello') {
    state.client = m.client;
    $('title').textContent = `raisov serve: ${m.name}`;
    const box = $('methods');
    box.innerHTML = '';
    m.methods.forEach((label, i) => {
      const l = document.createElement('label');
      l.innerHTML = `<input type="radio" name="method" value="${i}"> ${label}<br>`;
      l.querySelector('input').addEventListener('change', () => send(6, [], i));
      box.appendChild(l);
    });
    setMethod(m.method);
    state.stress = m.stress;
    setHolder(m.holder);
    state.budget = m.budget ?? null;
    state.maxFps = m.max_fps ?? 0;
  } else if (m.type === 'pins') {
    state.pins = m.pins;
    drawPins();
  } else if (m.type === 'error') {
    showError(m.message);
    // A refused cut (or any error while one is in flight) lets the next one go.
    cutDone();
  } else if (m.type === 'holder') {
    setHolder(m.holder);
  } else if (m.type === 'method') {
    setMethod(m.method);
    state.stress = m.stress;
  } else if (m.type === 'cut') {
    state.cuts = m.cuts;
    state.lastCut = m;
    $('cuts').textContent = `${m.cuts} (${m.nodes} nodes)`;
    if (m.client === state.client) cutDone();
  } else if (m.type === 'recording') {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([m.toml], { type: 'text/plain' }));
    a.download = 'recorded.toml';
    a.click();
    state.recording = m.toml;
  }
}

function setMethod(code) {
  state.method = code;
  document.querySelectorAll('input[name=method]').forEach((x) => { x.checked = Number(x.value) === code; });
}

function setHolder(h) {
  state.holder = h;
  $('holder').textContent = h === null ? 'free' : (h === state.client ? 'yours' : `client ${h} (watching)`);
}

function onTopology(dv) {
  const n = dv.getUint32(4, true);
  const m = dv.getUint32(8, true);
  const index = new Uint32Array(dv.buffer.slice(12, 12 + 12 * m));
  geometry.setIndex(new THREE.BufferAttribute(index, 1));
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * n), 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * n), 3));
  state.topology = { n, m };
  state.topologies++;
  state.firstPositions = null;
  legendMax = 0;
  // The camera stays where it is: a new topology after a cut shows the wound from the same view.
}

let legendMax = 0;
let lastFrameAt = performance.now();
function onFrame(dv, bytes) {
  if (!state.topology) return;
  const n = dv.getUint32(8, true);
  if (n !== state.topology.n) return;
  const flags = dv.getUint32(12, true);
  const st = new Float32Array(dv.buffer.slice(16, HEADER));
  const pos = new Float32Array(dv.buffer.slice(HEADER, HEADER + 12 * n));
  const scalar = new Float32Array(dv.buffer.slice(HEADER + 12 * n, HEADER + 16 * n));
  const pa = geometry.getAttribute('position');
  pa.array.set(pos);
  pa.needsUpdate = true;
  if (!state.firstPositions) state.firstPositions = pos.slice();
  state.positions = pos;
  // Colour: a legend maximum that rises at once and falls slowly (no flicker); it starts
  // afresh when the scalar changes (displacement in m, stress in Pa) or the topology does.
  const stressNow = (flags & FLAG.stress) !== 0;
  if (state.legendStress !== stressNow) { legendMax = 0; state.legendStress = stressNow; }
  const smax = st[STAT.scalarMax];
  legendMax = Math.max(smax, legendMax * 0.995, 1e-12);
  state.legendMax = legendMax;
  const ca = geometry.getAttribute('color');
  for (let i = 0; i < n; i++) {
    const k = Math.min(255, Math.max(0, Math.round((scalar[i] / legendMax) * 255)));
    ca.array[3 * i] = VIRIDIS[3 * k];
    ca.array[3 * i + 1] = VIRIDIS[3 * k + 1];
    ca.array[3 * i + 2] = VIRIDIS[3 * k + 2];
  }
  ca.needsUpdate = true;
  geometry.computeVertexNormals();
  geometry.computeBoundingSphere();
  if (!framed) frameCamera();
  const stress = stressNow;
  state.resting = (flags & FLAG.rest) !== 0;
  state.stuck = (flags & FLAG.stuck) !== 0;
  state.diverged = (flags & FLAG.diverged) !== 0;
  $('legendtitle').textContent = stress ? 'von Mises (kPa)' : '|u| (mm)';
  $('legendmax').textContent = stress ? (legendMax / 1e3).toPrecision(3) : (legendMax * 1e3).toPrecision(3);
  // Stats.
  state.frames++;
  state.bytesPerFrame = bytes;
  state.cycles = st[STAT.cycles];
  state.frameMethod = st[STAT.method];
  state.simFps = st[STAT.simFps];
  const f = [st[STAT.force], st[STAT.force + 1], st[STAT.force + 2]];
  state.force = f;
  state.forceN = Math.hypot(f[0], f[1], f[2]);
  $('simfps').textContent = `${st[STAT.simFps].toFixed(1)} fps`;
  $('residual').textContent = `${st[STAT.residual].toExponential(2)} N`;
  $('cycles').textContent = `${st[STAT.cycles]} (${st[STAT.frameMs].toFixed(1)} ms)`;
  // The budget meter: the frame's stepping time against the time it may take, the budget
  // (--budget-ms) or, with a cycle budget, the frame period of the cap (--max-fps).
  const allowed = state.budget && state.budget.ms ? state.budget.ms : (state.maxFps > 0 ? 1000 / state.maxFps : null);
  if (allowed && !state.resting) {
    const used = st[STAT.frameMs] / allowed;
    state.budgetUsed = used;
    $('budget').textContent = `${st[STAT.frameMs].toFixed(0)} / ${allowed.toFixed(0)} ms`;
    const bar = $('meterbar');
    bar.style.width = `${Math.min(100, 100 * used).toFixed(0)}%`;
    bar.style.background = used > 1.05 ? '#e63946' : (used > 0.9 ? '#f4a261' : '#5ec962');
  }
  $('lag').textContent = `${st[STAT.inputLag].toFixed(1)} ms`;
  state.serverLagMs = st[STAT.inputLag];
  $('bytes').textContent = `${(bytes / 1024).toFixed(1)} KiB`;
  $('force').textContent = `${state.forceN.toFixed(3)} N`;
  const holder = st[STAT.holder];
  $('grasped').textContent = holder >= 0 ? `${st[STAT.grasped]}` : '–';
  if (holder >= 0 && holder === state.client) {
    const s = st[STAT.appliedSeq];
    if (sentAt.has(s)) {
      const ms = performance.now() - sentAt.get(s);
      state.latencyMs = state.latencyMs === null ? ms : 0.8 * state.latencyMs + 0.2 * ms;
      // Every sample, for the browser test: end to end, the server's part, the frame period.
      if (state.latencySamples.length < 10000) {
        state.latencySamples.push({ e2e: ms, server: st[STAT.inputLag], frameMs: st[STAT.frameMs],
          period: st[STAT.simFps] > 0 ? 1000 / st[STAT.simFps] : null, method: st[STAT.method] });
      }
      sentAt.delete(s);
      $('e2e').textContent = `${state.latencyMs.toFixed(1)} ms`;
    }
  }
  const g = new THREE.Vector3(st[STAT.grasp], st[STAT.grasp + 1], st[STAT.grasp + 2]);
  if (holder >= 0) {
    grabMarker.visible = true;
    grabMarker.position.copy(g);
    grabMarker.scale.setScalar(diag * 0.006);
    if (state.forceN > 0) {
      arrow.visible = true;
      arrow.position.copy(g);
      arrow.setDirection(new THREE.Vector3(...f).normalize());
      // 0.1 N per 10 % of the organ's size, at most 40 %.
      const len = Math.min(0.4, state.forceN) * diag;
      arrow.setLength(Math.max(len, diag * 0.01), diag * 0.03, diag * 0.015);
    }
  } else {
    arrow.visible = false;
    grabMarker.visible = false;
  }
  state.residuals.push(st[STAT.residual]);
  if (state.residuals.length > 240) state.residuals.shift();
  drawPlot();
  lastFrameAt = performance.now();
}

function frameCamera() {
  geometry.computeBoundingBox();
  const b = geometry.boundingBox;
  const c = b.getCenter(new THREE.Vector3());
  diag = b.getSize(new THREE.Vector3()).length();
  controls.target.copy(c);
  camera.position.set(c.x + 0.35 * diag, c.y - 1.5 * diag, c.z + 0.35 * diag);
  camera.near = diag * 0.01;
  camera.far = diag * 20;
  camera.updateProjectionMatrix();
  sun.position.set(c.x + diag, c.y - 2 * diag, c.z + 2 * diag);
  controls.update();
  framed = true;
  drawPins();
}

function drawPlot() {
  const cv = $('plot');
  const g = cv.getContext('2d');
  g.clearRect(0, 0, cv.width, cv.height);
  const r = state.residuals.filter((x) => x > 0 && Number.isFinite(x)).map(Math.log10);
  if (r.length < 2) return;
  const lo = Math.floor(Math.min(...r));
  const hi = Math.ceil(Math.max(...r)) + (Math.min(...r) === Math.max(...r) ? 1 : 0);
  g.strokeStyle = '#444';
  g.fillStyle = '#aaa';
  g.font = '10px sans-serif';
  g.fillText(`1e${hi}`, 2, 10);
  g.fillText(`1e${lo}`, 2, cv.height - 2);
  g.strokeStyle = '#5ec962';
  g.beginPath();
  const w = cv.width - 34;
  state.residuals.forEach((x, i) => {
    const v = x > 0 ? Math.log10(x) : lo;
    const px = 34 + (i / 239) * w;
    const py = cv.height - ((v - lo) / (hi - lo)) * (cv.height - 4) - 2;
    if (i === 0) g.moveTo(px, py); else g.lineTo(px, py);
  });
  g.stroke();
}

(function drawLegend() {
  const cv = $('legend');
  const g = cv.getContext('2d');
  for (let y = 0; y < cv.height; y++) {
    const k = Math.round((1 - y / (cv.height - 1)) * 255);
    g.fillStyle = `rgb(${VIRIDIS[3 * k] * 255},${VIRIDIS[3 * k + 1] * 255},${VIRIDIS[3 * k + 2] * 255})`;
    g.fillRect(0, y, cv.width, 1);
  }
})();

// --- grasp, move, release, pin ---
const raycaster = new THREE.Raycaster();
const ndc = new THREE.Vector2();
const dragPlane = new THREE.Plane();
let dragging = false;
// The scalpel: a drag across the organ cuts it (cut messages, protocol kind 9).
let cutting = false;
let cutFrom = null; // { p: surface point (m), x, y: its screen position (px) }
let cutTo = null; // the newest surface point under the pointer not yet cut to
let cutInFlight = 0; // when the last cut was sent (ms), 0 when none is
const CUT_STEP_PX = 6;
const depth = () => Number($('depth').value) * 1e-2;
$('depth').addEventListener('input', () => { $('depthv').textContent = $('depth').value; });
// The trace of the drag, drawn over the organ.
const traceGeometry = new THREE.BufferGeometry();
traceGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * 512), 3));
traceGeometry.setDrawRange(0, 0);
const trace = new THREE.Line(traceGeometry, new THREE.LineBasicMaterial({ color: 0xffd166, depthTest: false }));
trace.renderOrder = 11;
trace.frustumCulled = false;
scene.add(trace);
function traceAdd(p, restart) {
  const a = traceGeometry.getAttribute('position');
  let k = restart ? 0 : traceGeometry.drawRange.count;
  if (k >= 512) k = 0;
  a.setXYZ(k, p.x, p.y, p.z);
  a.needsUpdate = true;
  traceGeometry.setDrawRange(0, k + 1);
}
function setScalpel(on) {
  state.scalpel = on;
  $('scalpel').textContent = on ? 'scalpel: on (c)' : 'scalpel: off (c)';
  $('scalpel').style.background = on ? '#e63946' : '';
  if (!on) endCut();
}
$('scalpel').addEventListener('click', () => setScalpel(!state.scalpel));
window.addEventListener('keydown', (e) => {
  if ((e.key === 'c' || e.key === 'C') && !e.ctrlKey && !e.metaKey && !e.altKey && !e.repeat) setScalpel(!state.scalpel);
});
// The unit view direction through the screen point (x, y) (px).
function viewRay(x, y) {
  const r = renderer.domElement.getBoundingClientRect();
  ndc.set(((x - r.left) / r.width) * 2 - 1, -((y - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  return raycaster.ray.direction.clone().normalize();
}
// Send the cut from `cutFrom` to `cutTo`: the edge between the two surface points, swept to the
// slider's depth along the view direction through the segment's midpoint on the screen. One cut
// is in flight at a time (until the server's `cut` reply or an error, at most 3 s): the pointer
// moves in the meantime make the next cut longer, not a queue of cuts behind a slow one.
function sendCut() {
  if (!cutFrom || !cutTo || (cutInFlight && performance.now() - cutInFlight < 3000)) return;
  const a = cutFrom.p;
  const b = cutTo.p;
  const w = viewRay((cutFrom.x + cutTo.x) / 2, (cutFrom.y + cutTo.y) / 2).multiplyScalar(depth());
  if (send(9, [a.x, a.y, a.z, b.x, b.y, b.z, w.x, w.y, w.z])) {
    state.cutsSent++;
    cutInFlight = performance.now();
    cutFrom = cutTo;
    cutTo = null;
  }
}
function cutDone() {
  if (cutInFlight) state.cutsAnswered++;
  cutInFlight = 0;
  sendCut(); // the points moved over meanwhile (the drag's last piece after it ended)
}
function endCut() {
  if (!cutting) return;
  if (cutTo) sendCut();
  cutting = false;
  controls.enabled = true;
}
let pendingMove = null;
const radius = () => Number($('radius').value) * 1e-3;
$('radius').addEventListener('input', () => { $('radiusv').textContent = $('radius').value; });

function pick(e) {
  const r = renderer.domElement.getBoundingClientRect();
  ndc.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(mesh, false);
  return hit.length ? hit[0].point : null;
}

function modifiers(e) {
  controls.enabled = !(e.shiftKey || e.ctrlKey || e.metaKey) && !dragging && !cutting;
}
window.addEventListener('keydown', modifiers);
window.addEventListener('keyup', modifiers);

renderer.domElement.addEventListener('pointerdown', (e) => {
  if (e.button !== 0) return;
  if (state.scalpel && !e.shiftKey && !e.ctrlKey && !e.metaKey) {
    // Scalpel: a drag that starts on the organ cuts; one that starts beside it orbits.
    const p = pick(e);
    if (!p) return;
    e.preventDefault();
    controls.enabled = false;
    cutting = true;
    renderer.domElement.setPointerCapture(e.pointerId);
    cutFrom = { p, x: e.clientX, y: e.clientY };
    cutTo = null;
    traceAdd(p, true);
  } else if (e.shiftKey) {
    const p = pick(e);
    if (!p) return;
    e.preventDefault();
    controls.enabled = false;
    dragging = true;
    renderer.domElement.setPointerCapture(e.pointerId);
    const dir = camera.getWorldDirection(new THREE.Vector3());
    dragPlane.setFromNormalAndCoplanarPoint(dir, p);
    sentAt.set(send(1, [p.x, p.y, p.z, radius()]), performance.now());
  } else if (e.ctrlKey || e.metaKey) {
    const p = pick(e);
    if (p) send(4, [p.x, p.y, p.z, radius()]);
  }
}, { capture: true });

renderer.domElement.addEventListener('pointermove', (e) => {
  if (cutting) {
    const last = cutTo ?? cutFrom;
    if (Math.hypot(e.clientX - last.x, e.clientY - last.y) < CUT_STEP_PX) return;
    const p = pick(e);
    if (!p) return; // beside the organ: the cut goes on from the last point on it
    cutTo = { p, x: e.clientX, y: e.clientY };
    traceAdd(p, false);
    sendCut();
    return;
  }
  if (!dragging) return;
  const r = renderer.domElement.getBoundingClientRect();
  ndc.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const t = raycaster.ray.intersectPlane(dragPlane, new THREE.Vector3());
  if (t) pendingMove = t;
});

function endDrag() {
  endCut();
  if (!dragging) return;
  dragging = false;
  pendingMove = null;
  send(3);
  controls.enabled = true;
}
renderer.domElement.addEventListener('pointerup', endDrag);
renderer.domElement.addEventListener('pointercancel', endDrag);

$('reset').addEventListener('click', () => send(5));
$('save').addEventListener('click', () => send(8));
document.querySelectorAll('input[name=colour]').forEach((x) => x.addEventListener('change', () => {
  send(7, [], Number(x.value));
}));

// --- the render loop: one move message per displayed frame at most ---
let shown = 0;
let fpsT = performance.now();
function loop() {
  requestAnimationFrame(loop);
  if (pendingMove && dragging) {
    const s = send(2, [pendingMove.x, pendingMove.y, pendingMove.z]);
    sentAt.set(s, performance.now());
    if (sentAt.size > 256) sentAt.delete(sentAt.keys().next().value);
    pendingMove = null;
  }
  controls.update();
  renderer.render(scene, camera);
  shown++;
  const now = performance.now();
  if (now - fpsT > 1000) {
    state.displayFps = (shown * 1000) / (now - fpsT);
    $('dispfps').textContent = `${state.displayFps.toFixed(1)} fps`;
    shown = 0;
    fpsT = now;
  }
  if (ws.readyState === WebSocket.OPEN) {
    let s = 'connected';
    if (state.diverged) s = 'diverged: press reset, or switch the method';
    else if (state.resting) s = 'at rest: the simulation sleeps until you grasp, pin or switch';
    else if (now - lastFrameAt > 3000) s = 'waiting for frames…';
    else if (state.stuck) s = 'the grasp cannot reach the cursor: move back towards the organ';
    else if (state.scalpel) s = `scalpel: drag across the organ to cut ${$('depth').value} cm deep (c leaves)`;
    $('status').textContent = s;
  }
}
loop();
