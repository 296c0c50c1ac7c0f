// The WebAssembly decoder against the native one (spec/web.md §4): decodes FILE at COUNT times
// spread over its range with web/dist/facemorph_wasm.{mjs,wasm} under node, reads the native
// decoder's record of the same times (tests/c_frames.c --web), and reports the largest vertex
// difference as a fraction of the first frame's bounding-box diagonal. Exits 1 above TOLERANCE.
//   node web/test/exactness.mjs FILE.fmv NATIVE.bin [COUNT=20] [TOLERANCE=1e-6]
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { loadFacemorph } from '../facemorph_wasm.js';

const [file, nativePath, countText = '20', toleranceText = '1e-6'] = process.argv.slice(2);
const count = Number(countText), tolerance = Number(toleranceText);
const dist = join(dirname(fileURLToPath(import.meta.url)), '..', 'dist');
const { default: createModule } = await import(join(dist, 'facemorph_wasm.mjs'));
const fm = await loadFacemorph(createModule, readFileSync(join(dist, 'facemorph_wasm.wasm')));
const opened = fm.openBytes(readFileSync(file));
const info = opened.info();
const decoder = opened.createDecoder();
// The texture's weights before any frame was decoded: a module without image codecs must give them
// without decoding a texture (fm_decoder_get_texture_weights decodes the frame without it).
if (info.textureSize > 0) {
  const weights = decoder.textureWeights(info.firstTime + 0.4 * info.duration);
  const sum = weights.reduce((a, w) => a + w.weight, 0);
  if (!(weights.length >= 1 && Math.abs(sum - 1) < 1e-6)) throw new Error(`texture weights ${JSON.stringify(weights)} do not sum to 1`);
}

const native = readFileSync(nativePath);
const view = new DataView(native.buffer, native.byteOffset, native.byteLength);
let at = 0, worst = 0, worstTime = 0, diagonal = 0, decodeMs = 0;
for (let i = 0; i < count; ++i) {
  const t = info.rangeBegin + (info.rangeEnd - info.rangeBegin) * i / (count - 1);
  const nativeTime = view.getFloat64(at, true);
  const vertices = view.getUint32(at + 8, true);
  at += 12;
  if (nativeTime !== t) throw new Error(`time ${i}: native ${nativeTime}, here ${t}`);
  const start = performance.now();
  const frame = decoder.decode(t, 0);  // positions, normals, UVs, indices: what the page asks for, as c_frames --web does
  decodeMs += performance.now() - start;
  if (frame.vertexCount !== vertices) throw new Error(`t = ${t}: ${frame.vertexCount} vertices here, ${vertices} native`);
  const theirs = new Float32Array(native.buffer.slice(native.byteOffset + at, native.byteOffset + at + 12 * vertices));
  at += 12 * vertices;
  if (i === 0) {
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let v = 0; v < vertices; ++v) for (let k = 0; k < 3; ++k) {
      lo[k] = Math.min(lo[k], theirs[3 * v + k]);
      hi[k] = Math.max(hi[k], theirs[3 * v + k]);
    }
    diagonal = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  }
  for (let v = 0; v < vertices; ++v) {
    const d = Math.hypot(frame.positions[3 * v] - theirs[3 * v], frame.positions[3 * v + 1] - theirs[3 * v + 1], frame.positions[3 * v + 2] - theirs[3 * v + 2]);
    if (d > worst) { worst = d; worstTime = t; }
  }
}
if (at !== native.byteLength) throw new Error(`the native record has ${native.byteLength - at} bytes more than ${count} frames`);
const relative = worst / diagonal;
console.log(`exactness: ${file}: ${count} times over [${info.rangeBegin}, ${info.rangeEnd}] s, N = ${info.gridN}: ` +
            `largest vertex difference ${worst.toExponential(3)} ${info.units} = ${relative.toExponential(3)} of the bbox diagonal ` +
            `(at t = ${worstTime.toFixed(4)} s; tolerance ${tolerance}); WebAssembly decode ${(decodeMs / count).toFixed(2)} ms a frame`);
decoder.destroy();
opened.close();
process.exit(relative <= tolerance ? 0 : 1);
