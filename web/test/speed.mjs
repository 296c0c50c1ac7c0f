// The WebAssembly decoder's speed under node (V8, the engine Chromium runs it with): each FILE
// opened, FRAMES frames decoded over its capture's span at even steps (positions, normals, UVs,
// indices, as the page asks), ms per frame: mean, median, worst; the first frame (keyframes
// reconstructed, G and its solver built) apart.
//   node web/test/speed.mjs [--frames 120] FILE.fmv...
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { loadFacemorph } from '../facemorph_wasm.js';

const args = process.argv.slice(2);
let frames = 120;
const files = [];
for (let i = 0; i < args.length; ++i) {
  if (args[i] === '--frames') frames = Number(args[++i]);
  else files.push(args[i]);
}
const dist = join(dirname(fileURLToPath(import.meta.url)), '..', 'dist');
const { default: createModule } = await import(join(dist, 'facemorph_wasm.mjs'));
const fm = await loadFacemorph(createModule, readFileSync(join(dist, 'facemorph_wasm.wasm')));
for (const file of files) {
  const opened = fm.openBytes(readFileSync(file));
  const info = opened.info();
  const decoder = opened.createDecoder();
  const times = [];
  let first = 0;
  for (let k = 0; k <= frames; ++k) {
    const t = info.firstTime + (info.duration * k) / frames;
    const start = performance.now();
    decoder.decode(t, 1);
    const ms = performance.now() - start;
    if (k === 0) first = ms; else times.push(ms);
  }
  const sorted = [...times].sort((a, b) => a - b);
  const mean = times.reduce((a, b) => a + b, 0) / times.length;
  console.log(`${file}: N = ${info.gridN}, ${info.keyframeCount} keyframes: first frame ${first.toFixed(1)} ms; then ${frames} frames: ` +
              `mean ${mean.toFixed(2)} ms, median ${sorted[sorted.length >> 1].toFixed(2)} ms, worst ${sorted[sorted.length - 1].toFixed(2)} ms ` +
              `(${(1000 / mean).toFixed(0)} fps); heap ${(fm.heapBytes() / 2 ** 20).toFixed(0)} MiB`);
  decoder.destroy();
  opened.close();
}
