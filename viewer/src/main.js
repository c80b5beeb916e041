// The tissue viewer page: connects to `tissue view` over a WebSocket, draws what the
// simulation sends, and turns the mouse and keys into commands (JSON messages).
import * as THREE from 'three';
import { Orbit } from './orbit.js';
import { Organ } from './organ.js';
import { RollingPlot } from './plot.js';
import { legendGradient } from './colormap.js';

const $ = (id) => document.getElementById(id);
const view = $('view');
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(Math.min(2, window.devicePixelRatio || 1));
renderer.setClearColor(0x1b1d23);
renderer.toneMapping = THREE.ACESFilmicToneMapping;
renderer.toneMappingExposure = 1.1;
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 0.001, 100);
// Three-point lighting around the organ (placed in onInit): a warm key light above and to
// the side, a cool dimmer fill from the other side, a rim light from behind that outlines
// the silhouette; a faint sky/ground ambient keeps the shadows from going black.
scene.add(new THREE.HemisphereLight(0xdde6ff, 0x2a1a18, 0.5));
const sun = new THREE.DirectionalLight(0xfff1e0, 2.6);
const fill = new THREE.DirectionalLight(0xc8d8ff, 0.9);
const rim = new THREE.DirectionalLight(0xffffff, 1.6);
scene.add(sun, fill, rim);
const orbit = new Orbit(camera, renderer.domElement);
const organ = new Organ(scene);
const plot = new RollingPlot($('plot'));
const banner = document.createElement('div');
banner.id = 'error-banner';
view.appendChild(banner);

// What the tests (scripts/browser-test.sh) read.
const state = {
  ready: false, frames: 0, inits: 0, init: null, last: null,
  tool: 'probe', depth: 1.0, forceMagnitude: 0, pressPeak: 0, notices: [],
  // Frames the organ could not show (a surface of another size: a new init on its way).
  skippedFrames: 0,
};
window.__tissue = state;

// ---------------------------------------------------------------- connection
let ws = null;
let pendingFrame = null;
function send(obj) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj));
}
state.send = send;
state.sendRaw = (text) => ws && ws.readyState === WebSocket.OPEN && ws.send(text);

function connect() {
  // The session token `tissue view` printed in the page's URL (docs/security.md).
  const token = new URLSearchParams(location.search).get('token') || '';
  ws = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(token)}`);
  ws.onopen = () => { $('status').textContent = 'connected'; };
  ws.onclose = () => {
    $('status').textContent = 'disconnected: reconnecting…';
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    // Frames come at ~30 Hz; a slow page (software WebGL, a big voxel organ) draws fewer:
    // only the newest is parsed and applied, once per drawn frame.
    if (typeof ev.data === 'string' && ev.data.includes('"type":"frame"')) { pendingFrame = ev.data; return; }
    let msg;
    try { msg = JSON.parse(ev.data); } catch { return notice('error', 'unreadable message from the server'); }
    if (msg.type === 'init') onInit(msg);
    else if (msg.type === 'frame') onFrame(msg);
    else if (msg.type === 'notice') {
      // The server says "reset" after it has reset the organ, and sends every later frame
      // after this notice: a frame still waiting here shows the organ before the reset, so it
      // is dropped, and the colour scales start again from the next frame.
      if (msg.message.startsWith('reset to the rest state')) { pendingFrame = null; organ.rescale(); }
      notice(msg.level, msg.message);
    }
  };
}

function notice(level, message) {
  state.notices.push({ level, message });
  const li = document.createElement('li');
  li.className = level;
  li.textContent = message;
  $('log').prepend(li);
  while ($('log').children.length > 50) $('log').lastChild.remove();
  if (level === 'error') {
    banner.textContent = message;
    banner.style.display = 'block';
    clearTimeout(banner.timer);
    banner.timer = setTimeout(() => { banner.style.display = 'none'; }, 6000);
  }
}

function onInit(msg) {
  const first = !state.init;
  state.init = msg;
  state.inits += 1;
  organ.init(msg);
  const c = new THREE.Vector3(...msg.center);
  if (first) orbit.frame(c, msg.size);
  sun.position.set(c.x + msg.size * 2, c.y + msg.size * 3, c.z + msg.size * 2);
  fill.position.set(c.x - msg.size * 3, c.y + msg.size * 0.5, c.z + msg.size * 1.5);
  rim.position.set(c.x - msg.size * 0.5, c.y + msg.size * 2, c.z - msg.size * 3);
  for (const l of [sun, fill, rim]) { l.target.position.copy(c); l.target.updateMatrixWorld(); }
  const sel = $('kind');
  sel.innerHTML = '';
  for (const k of msg.kinds) {
    const o = document.createElement('option');
    o.value = k.name; o.textContent = k.name; o.title = k.summary;
    sel.appendChild(o);
  }
  sel.value = msg.kind;
  $('kind-summary').textContent = (msg.kinds.find((k) => k.name === msg.kind) || {}).summary || '';
  $('young').value = msg.material.young_modulus;
  $('poisson').value = msg.material.poisson_ratio;
  showStatus(null);
  updateLegend();
  state.ready = true;
}

// The status line: the scene, the running model, its dt and substeps; a build in progress
// and a cut in progress below it.
function showStatus(frame) {
  const init = state.init;
  if (!init) return;
  const kind = (frame && frame.kind) || init.kind;
  const dt = frame ? frame.dt : init.dt;
  let step;
  if (init.is_static) step = 'static';
  else {
    const sub = frame && frame.substeps > 1 ? ` in ${frame.substeps} substeps` : '';
    step = `dt ${Number(dt).toExponential(2)} s${sub}`;
  }
  // The scene's fine surface is drawn over the mechanical one until a cut (`visual`).
  const drawn = init.visual ? ` (drawn: its ${init.visual}-vertex visual surface)` : '';
  const name = init.scene.split('/').pop();
  $('status').textContent = `${name}${drawn}: running ${kind}, ${step}`;
  state.status = $('status').textContent;
  const b = frame && frame.building;
  const bar = $('build');
  if (b) {
    const pct = b.percent === null || b.percent === undefined ? null : b.percent;
    bar.style.display = 'block';
    $('build-text').textContent = `building ${b.kind}: ${b.stage}${pct === null ? '' : ` ${pct.toFixed(0)} %`} (${b.seconds.toFixed(0)} s)`;
    $('build-bar').style.width = pct === null ? '100%' : `${pct}%`;
    $('build-bar').classList.toggle('unknown', pct === null);
  } else bar.style.display = 'none';
  state.buildText = b ? $('build-text').textContent : '';
  const cut = frame && frame.cut;
  // A long incision (bem) is computed off the simulation thread after the blade's path.
  const bg = frame && frame.background;
  $('cut-progress').textContent = cut ? `cutting: ${cut.done} of ${cut.total} path points swept`
    : (bg ? `${bg}; the simulation goes on` : '');
}

// The colour legend: the map, its range in mm and the quantity.
function updateLegend() {
  const on = $('cmap').checked;
  $('legend').style.display = on ? 'block' : 'none';
  $('legend-bar').style.background = legendGradient();
  const strain = organ.quantity === 'strain' && organ.hasStrain();
  if (strain) {
    const pct = organ.strainScale * 100;
    $('legend-lo').textContent = '0 %';
    $('legend-hi').textContent = `${pct < 10 ? pct.toFixed(2) : pct.toFixed(1)} %`;
    $('legend-title').textContent = 'equivalent strain √(2/3 dev E : dev E), Green-Lagrange (scale grows with the largest, reset with R)';
  } else {
    const mm = organ.colourScale * 1000;
    $('legend-lo').textContent = '0 mm';
    $('legend-hi').textContent = `${mm < 10 ? mm.toFixed(2) : mm.toFixed(1)} mm`;
    $('legend-title').textContent = organ.quantity === 'strain'
      ? 'displacement |u| (this model has no tetrahedra: no strain to show)'
      : 'displacement |u| (scale grows with the largest, reset with R)';
  }
  state.legend = on ? `${$('legend-lo').textContent} – ${$('legend-hi').textContent}` : '';
}

function onFrame(msg) {
  state.last = msg;
  state.frames += 1;
  const shown = organ.frame(msg);
  if (shown === undefined) state.skippedFrames += 1;
  const n = shown || 0;
  state.forceMagnitude = n;
  // The server's largest probe force of this press: a frame is one instant, and a force that
  // lasts a few steps (a soft membrane denting past the probe) falls between slow frames.
  state.pressPeak = msg.probe_active && Number.isFinite(msg.press_peak) ? msg.press_peak : 0;
  state.maxDisplacement = organ.maxDisplacement;
  state.openEdges = organ.openEdges ? organ.openEdges.length / 2 : 0;
  plot.push(n);
  const f = msg.grasper ? msg.grasper.force : msg.haptic_force;
  $('sim-rate').textContent = `${msg.sim_rate.toFixed(0)} steps/s`;
  $('haptic-rate').textContent = `${msg.haptic_rate.toFixed(0)} Hz, p99 ${msg.haptic_p99_us.toFixed(0)} µs`;
  $('time').textContent = `${msg.time.toFixed(2)} s`;
  showStatus(msg);
  updateLegend();
  $('force').textContent = `${n.toFixed(4)} N${state.pressPeak > 0 ? ` (press peak ${state.pressPeak.toFixed(4)} N)` : ''}`;
  $('force-vec').textContent = f.map((x) => x.toFixed(3)).join(', ');
  $('disp').textContent = `${(organ.maxDisplacement * 1000).toFixed(2)} mm`;
}

// ---------------------------------------------------------------- tools
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let action = null; // the tool in use while the left button is down
let hover = null;  // the last pointer position over the canvas

function ray(e) {
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  return raycaster;
}

function hit(e, mesh) {
  if (!mesh) return null;
  const h = ray(e).intersectObject(mesh, false)[0];
  if (!h) return null;
  const n = h.face ? h.face.normal.clone() : new THREE.Vector3(0, 1, 0);
  // Outward normal: towards the viewer for a front hit.
  if (n.dot(raycaster.ray.direction) > 0) n.negate();
  return { point: h.point.clone(), normal: n };
}

function setTool(t) {
  state.tool = t;
  for (const b of document.querySelectorAll('.tool')) b.classList.toggle('active', b.dataset.tool === t);
  organ.ghost.visible = false;
}

function probeTarget(e) {
  // Picked on the rest surface: pushing moves the deformed surface away, the rest one stays.
  const h = hit(e, organ.restMesh);
  if (!h) return null;
  const r = state.init.probe_radius;
  return h.point.add(h.normal.multiplyScalar(r - state.depth * r));
}

const canvas = renderer.domElement;
canvas.addEventListener('pointerdown', (e) => {
  if (e.button !== 0 || !state.init) return;
  canvas.setPointerCapture(e.pointerId);
  hover = e;
  if (state.tool === 'probe') {
    action = { tool: 'probe', start: performance.now(), last: null };
  } else if (state.tool === 'grasp') {
    const h = hit(e, organ.mesh);
    if (!h) return;
    const normal = camera.getWorldDirection(new THREE.Vector3());
    action = { tool: 'grasp', plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, h.point) };
    send({ type: 'grasp', position: h.point.toArray() });
  } else if (state.tool === 'scalpel') {
    const h = hit(e, organ.mesh);
    action = { tool: 'scalpel', points: h ? [h.point] : [] };
  }
});

canvas.addEventListener('pointermove', (e) => {
  hover = e;
  if (!action) {
    if (state.tool === 'probe' && state.init) {
      const h = hit(e, organ.mesh);
      organ.ghost.visible = !!h;
      if (h) organ.ghost.position.copy(h.point.add(h.normal.multiplyScalar(state.init.probe_radius)));
    }
    return;
  }
  if (action.tool === 'grasp') {
    const p = ray(e).ray.intersectPlane(action.plane, new THREE.Vector3());
    if (p) send({ type: 'grasp', position: p.toArray() });
  } else if (action.tool === 'scalpel') {
    const h = hit(e, organ.mesh);
    const last = action.points[action.points.length - 1];
    if (h && (!last || last.distanceTo(h.point) > state.init.size * 0.01) && action.points.length < 250) {
      action.points.push(h.point);
      organ.showCutPath(action.points);
    }
  }
});

function endAction() {
  if (!action) return;
  if (action.tool === 'probe') send({ type: 'probe', position: null });
  else if (action.tool === 'grasp') send({ type: 'release' });
  else if (action.tool === 'scalpel') {
    if (action.points.length >= 2) {
      const into = camera.getWorldDirection(new THREE.Vector3());
      send({ type: 'cut', path: action.points.map((p) => p.toArray()), into: into.toArray() });
    } else notice('error', 'draw a longer scalpel path over the organ');
    organ.showCutPath([]);
  }
  action = null;
}
canvas.addEventListener('pointerup', (e) => { if (e.button === 0) endAction(); });
canvas.addEventListener('pointercancel', endAction);

// The probe pushes in over 0.4 s while the button is held, following the pointer.
function updateProbe() {
  if (!action || action.tool !== 'probe' || !hover) return;
  const ramp = Math.min(1, (performance.now() - action.start) / 400);
  const saved = state.depth;
  state.depth = saved * ramp;
  const p = probeTarget(hover);
  state.depth = saved;
  if (!p) return;
  if (!action.last || action.last.distanceTo(p) > 1e-6) {
    action.last = p;
    send({ type: 'probe', position: p.toArray() });
  }
}

// ---------------------------------------------------------------- panel and keys
for (const b of document.querySelectorAll('.tool')) b.addEventListener('click', () => setTool(b.dataset.tool));
$('wire').addEventListener('change', (e) => organ.setWireframe(e.target.checked));
$('cmap').addEventListener('change', (e) => { organ.setColours(e.target.checked); updateLegend(); });
$('quantity').addEventListener('change', (e) => {
  organ.setQuantity(e.target.value);
  if (!$('cmap').checked) { $('cmap').checked = true; organ.setColours(true); }
  updateLegend();
  e.target.blur();
});
// After a choice the selector lets go of the keyboard, so the shortcuts work again (a
// focused select would take C, R, W... as type-to-search).
$('kind').addEventListener('change', (e) => { send({ type: 'set_model', kind: e.target.value }); e.target.blur(); });
$('reset').addEventListener('click', () => send({ type: 'reset' }));
for (const el of document.querySelectorAll('button, input[type=checkbox]')) {
  el.addEventListener('click', () => el.blur());
}
$('apply-material').addEventListener('click', () => send({
  type: 'set_material',
  young_modulus: Number($('young').value),
  poisson_ratio: Number($('poisson').value),
}));

const SHORTCUTS = new Set(['1', '2', '3', 'w', 'c', 'f', 'r', '[', ']', 'm']);
// Captured on the window before any control sees it: shortcuts work whatever has focus,
// except while typing a number into a field.
window.addEventListener('keydown', (e) => {
  if (e.ctrlKey || e.metaKey || e.altKey) return;
  const typing = e.target instanceof HTMLInputElement && e.target.type !== 'checkbox';
  if (typing) return;
  const k = e.key.toLowerCase();
  if (!SHORTCUTS.has(k)) return;
  if (e.target instanceof HTMLElement && e.target !== document.body) e.target.blur();
  if (k === '1') setTool('probe');
  else if (k === '2') setTool('grasp');
  else if (k === '3') setTool('scalpel');
  else if (k === 'w') { $('wire').checked = !$('wire').checked; organ.setWireframe($('wire').checked); }
  else if (k === 'c') { $('cmap').checked = !$('cmap').checked; organ.setColours($('cmap').checked); updateLegend(); }
  else if (k === 'f') organ.setShowFixed(!organ.showFixed);
  else if (k === 'r') send({ type: 'reset' });
  else if (k === '[') state.depth = Math.max(0.1, state.depth - 0.1);
  else if (k === ']') state.depth = Math.min(3, state.depth + 0.1);
  else if (k === 'm' && state.init) {
    const names = state.init.kinds.map((x) => x.name);
    send({ type: 'set_model', kind: names[(names.indexOf(state.init.kind) + 1) % names.length] });
  } else return;
  e.preventDefault();
  e.stopPropagation();
}, { capture: true });

// ---------------------------------------------------------------- test hooks
// Screen point (CSS pixels, page coordinates) of a world point.
state.screenOf = (p) => {
  const v = new THREE.Vector3(...p).project(camera);
  const r = canvas.getBoundingClientRect();
  return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
};
// A screen point whose ray hits the organ near its middle.
state.organScreenPoint = () => {
  const c = state.init.center;
  const [x, y] = state.screenOf(c);
  const probe = { clientX: x, clientY: y };
  return hit(probe, organ.mesh) ? [x, y] : null;
};
// Pixels of the rendered frame with the tissue's reddish colour, and the total.
state.organPixels = () => {
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let organ = 0;
  for (let i = 0; i < px.length; i += 4) {
    if (px[i] > px[i + 1] + 25 && px[i] > px[i + 2] + 25) organ += 1;
  }
  return { organ, total: w * h };
};
// Pixels of the drawn scalpel path (yellow) in the rendered frame.
state.pathPixels = () => {
  const px = readFrame();
  let n = 0;
  for (let i = 0; i < px.length; i += 4) if (px[i] > 200 && px[i + 1] > 180 && px[i + 2] < 110) n += 1;
  return n;
};
// A coarse grey image of the frame (every 2nd pixel each way), kept on the page under
// `name` (sending it to the test costs seconds); `changedPixels` compares two of them.
const snapshots = {};
state.snapshot = (name) => { snapshots[name] = grey(); return snapshots[name].length; };
state.changedPixels = (a, b) => {
  const x = snapshots[a], y = snapshots[b];
  let n = 0;
  for (let i = 0; i < Math.min(x.length, y.length); i++) if (Math.abs(x[i] - y[i]) > 24) n += 1;
  return n;
};
function grey() {
  const px = readFrame();
  const w = renderer.getContext().drawingBufferWidth;
  const out = [];
  for (let i = 0; i < px.length; i += 4) {
    const p = i / 4;
    if ((p % w) % 2 || Math.floor(p / w) % 2) continue;
    out.push(Math.round(0.3 * px[i] + 0.59 * px[i + 1] + 0.11 * px[i + 2]));
  }
  return out;
}
function readFrame() {
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const px = new Uint8Array(gl.drawingBufferWidth * gl.drawingBufferHeight * 4);
  gl.readPixels(0, 0, gl.drawingBufferWidth, gl.drawingBufferHeight, gl.RGBA, gl.UNSIGNED_BYTE, px);
  return px;
}

// ---------------------------------------------------------------- render loop
function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();
setTool('probe');

let fpsCount = 0;
let fpsStart = performance.now();
function animate() {
  fpsCount += 1;
  const now = performance.now();
  if (now - fpsStart >= 1000) {
    state.fps = (1000 * fpsCount) / (now - fpsStart);
    $('fps').textContent = `${state.fps.toFixed(0)} frames/s`;
    fpsCount = 0;
    fpsStart = now;
  }
  if (pendingFrame) {
    const text = pendingFrame;
    pendingFrame = null;
    let msg = null;
    try { msg = JSON.parse(text); } catch { notice('error', 'unreadable frame from the server'); }
    if (msg) onFrame(msg);
  }
  updateProbe();
  plot.draw();
  renderer.render(scene, camera);
  requestAnimationFrame(animate);
}
connect();
animate();
