// The player page (web/index.html): open or drop a .fmv (or ?file=URL), play, pause, scrub over the
// whole range the file serves (the extrapolated ends included), speed, wireframe and texture, the
// frame rate, decode time, bytes fetched and memory shown. The view is fmdec --preview's: an
// orthographic camera looking down -z at the face turned by `yaw` about the vertical, fitted to
// the frame with a 5% margin, on white.
//
// window.facemorphPage is what the browser test (tests/web/browser.mjs) drives: open(url),
// seek(t) (resolves once that frame has been drawn), play(), pause(), stats().
import * as THREE from 'three';
import { FacemorphPlayer, FacemorphThree } from './facemorph.js';

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setClearColor(0xffffff, 1);
const scene = new THREE.Scene();
const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, -1000, 1000);
camera.position.set(0, 0, 0);

let player = null, face = null;
let playing = false, t = 0, lastTick = 0, speed = 1;
let yaw = 20 * Math.PI / 180;
const frameTimes = [], decodeTimes = [];
let drawn = 0, lastFrame = null;
const page = { state: 'idle', error: null, drawn: 0 };
window.facemorphPage = page;

// Resizing clears the canvas: drawn again at once.
function resize() {
  const size = Math.round(canvas.clientWidth) || 800;
  if (canvas.width === size && canvas.height === size) return;
  renderer.setSize(size, size, false);
  renderer.render(scene, camera);
}
window.addEventListener('resize', resize);

// fmdec --preview's framing: the drawn vertices' extent in x and y after the turn, 5% margin.
function fit(frame) {
  const c = Math.cos(yaw), s = Math.sin(yaw);
  let xmin = Infinity, xmax = -Infinity, ymin = Infinity, ymax = -Infinity;
  const p = frame.positions;
  for (let i = 0; i < 3 * frame.vertexCount; i += 3) {
    const x = c * p[i] + s * p[i + 2], y = p[i + 1];
    if (x < xmin) xmin = x; if (x > xmax) xmax = x;
    if (y < ymin) ymin = y; if (y > ymax) ymax = y;
  }
  const extent = Math.max(xmax - xmin, ymax - ymin) / (1 - 2 * 0.05);
  const cx = (xmin + xmax) / 2, cy = (ymin + ymax) / 2;
  camera.left = cx - extent / 2; camera.right = cx + extent / 2;
  camera.bottom = cy - extent / 2; camera.top = cy + extent / 2;
  const depth = 10 * extent + 10;
  camera.near = -depth; camera.far = depth;
  camera.updateProjectionMatrix();
}

function showStats() {
  if (!player) return;
  const info = player.info();
  const rate = frameTimes.length > 1 ? (frameTimes.length - 1) / ((frameTimes[frameTimes.length - 1] - frameTimes[0]) / 1000) : 0;
  const decode = decodeTimes.length ? decodeTimes.reduce((a, b) => a + b, 0) / decodeTimes.length : 0;
  const heap = lastFrame ? lastFrame.heapBytes : 0;
  const js = performance.memory ? performance.memory.usedJSHeapSize : 0;
  $('stats').textContent =
    `N = ${info.gridN}, ${lastFrame ? lastFrame.vertexCount : 0} vertices, ${info.keyframeCount} keyframes, texture ${info.textureSize}²   ` +
    `${rate.toFixed(1)} fps drawn, decode ${decode.toFixed(1)} ms a frame   ` +
    `fetched ${(lastFrame ? lastFrame.bytesFetched : player.openStats().bytesFetched) / 1024 | 0} of ${player.openStats().fileBytes / 1024 | 0} kB   ` +
    `memory: decoder ${(heap / 2 ** 20).toFixed(0)} MiB${js ? `, page ${(js / 2 ** 20).toFixed(0)} MiB` : ''}`;
}

function showClock() {
  const info = player.info();
  $('clock').value = `${t.toFixed(3)} s of [${info.rangeBegin.toFixed(2)}, ${info.rangeEnd.toFixed(2)}]`;
  $('time').value = String(t);
}

// Decodes t and draws it; resolves with the frame once it is on the canvas.
async function show(time) {
  t = time;
  const frame = await face.update(t);
  lastFrame = frame;
  decodeTimes.push(frame.decodeMs);
  if (decodeTimes.length > 60) decodeTimes.shift();
  face.mesh.rotation.y = yaw;
  fit(frame);
  renderer.render(scene, camera);
  drawn += 1;
  page.drawn = drawn;
  frameTimes.push(performance.now());
  if (frameTimes.length > 60) frameTimes.shift();
  showClock();
  showStats();
  return frame;
}

function tick(now) {
  if (!playing || !face) return;
  const info = player.info();
  const dt = lastTick ? (now - lastTick) / 1000 : 0;
  lastTick = now;
  let next = t + dt * speed;
  if (next > info.rangeEnd) next = info.rangeBegin;  // loop over the whole served range
  if (!face.busy) show(next).catch(fail);
  requestAnimationFrame(tick);
}

function play() {
  if (!player || playing) return;
  playing = true;
  lastTick = 0;
  $('play').textContent = 'Pause';
  requestAnimationFrame(tick);
}
function pause() {
  playing = false;
  $('play').textContent = 'Play';
}

function fail(error) {
  page.state = 'error';
  page.error = String(error.message || error);
  $('drop').textContent = page.error;
  $('drop').style.display = '';
  console.error(error);
}

// No file: nothing drawn, nothing to play or scrub. Where every open starts, so a failed one leaves
// its error on an empty view, not the last file's face under it with live controls.
function clear() {
  pause();
  if (face) { scene.remove(face.mesh); face.dispose(); }
  player?.close();
  player = null;
  face = null;
  lastFrame = null;
  $('play').disabled = true;
  $('time').disabled = true;
  $('clock').value = '–';
  $('stats').textContent = '';
  renderer.render(scene, camera);
}

async function open(source, name) {
  clear();
  page.state = 'opening';
  page.error = null;
  $('drop').textContent = `Opening ${name}…`;
  $('drop').style.display = '';
  player = await FacemorphPlayer.open(source, { name });
  face = new FacemorphThree(THREE, player);
  face.wireframe = $('wireframe').checked;
  face.textured = $('texture').checked;
  scene.add(face.mesh);
  const info = player.info();
  const time = $('time');
  time.min = String(info.rangeBegin);
  time.max = String(info.rangeEnd);
  time.step = String(Math.max((info.rangeEnd - info.rangeBegin) / 2000, 1e-4));
  time.disabled = false;
  $('play').disabled = false;
  $('drop').style.display = 'none';
  resize();
  await show(info.firstTime);
  page.state = 'opened';
  page.name = name;
  return info;
}

// Rejects as the page's own open does, after showing the error.
page.open = (url) => open(url, url).catch((error) => { fail(error); throw error; });
page.seek = (time) => show(time);
page.play = play;
page.pause = pause;
// The canvas as drawn last (a PNG data URL): what the browser test compares with fmdec --preview.
page.snapshot = () => canvas.toDataURL('image/png');
page.setYaw = (degrees) => { yaw = degrees * Math.PI / 180; };
// What a person sees of the controls: whether Play and the time slider take input.
page.controls = () => ({ play: !$('play').disabled, time: !$('time').disabled });
page.stats = () => ({
  info: player?.info(), open: player?.openStats(), lastFrame: lastFrame && { time: lastFrame.time, vertexCount: lastFrame.vertexCount, decodeMs: lastFrame.decodeMs, bytesFetched: lastFrame.bytesFetched, requests: lastFrame.requests, heapBytes: lastFrame.heapBytes },
  decodeMs: [...decodeTimes], drawn,
});

$('play').onclick = () => (playing ? pause() : play());
$('time').oninput = () => { pause(); if (face && !face.busy) show(Number($('time').value)).catch(fail); };
$('speed').onchange = () => { speed = Number($('speed').value); };
$('wireframe').onchange = () => { if (face) { face.wireframe = $('wireframe').checked; show(t).catch(fail); } };
$('texture').onchange = () => { if (face) { face.textured = $('texture').checked; show(t).catch(fail); } };
$('yaw').oninput = () => { yaw = Number($('yaw').value) * Math.PI / 180; if (face && !playing) show(t).catch(fail); };
$('file').onchange = () => { const file = $('file').files[0]; if (file) open(file, file.name).catch(fail); };
const stage = $('stage');
stage.ondragover = (event) => { event.preventDefault(); stage.classList.add('dragging'); };
stage.ondragleave = () => stage.classList.remove('dragging');
stage.ondrop = (event) => {
  event.preventDefault();
  stage.classList.remove('dragging');
  const file = event.dataTransfer.files[0];
  if (file) open(file, file.name).catch(fail);
};

resize();
renderer.render(scene, camera);
const requested = new URLSearchParams(location.search).get('file');
if (requested) open(requested, requested).then(() => { if (new URLSearchParams(location.search).has('play')) play(); }).catch(fail);
page.ready = true;
