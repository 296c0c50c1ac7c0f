// One file of the hostile set (tests/decoder/hostile_corpus.cpp) through the WebAssembly decoder at
// its default limits (web/dist/facemorph_wasm.{mjs,wasm}, the C API as the worker calls it): open
// the bytes, read the info and the keyframe times, create a decoder and decode at each of TIMES
// (one call each, as fmdec does; a call the work limit stops is a named refusal). Prints a line a
// step. Exits 0 when every frame decoded with finite positions, 1 on a named refusal (a
// FacemorphError: its status name and the library's message, after the file's name: the module
// names bytes it is handed "memory"), 2 on anything else (a trap, an abort: a crash).
//   node web/test/hostile.mjs FILE.fmv TIMES
import { readFileSync } from 'node:fs';
import { basename, dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { FacemorphError, loadFacemorph } from '../facemorph_wasm.js';

const [file, timesText = ''] = process.argv.slice(2);
const name = basename(file);
const dist = join(dirname(fileURLToPath(import.meta.url)), '..', 'dist');
const { default: createModule } = await import(join(dist, 'facemorph_wasm.mjs'));
const fm = await loadFacemorph(createModule, readFileSync(join(dist, 'facemorph_wasm.wasm')));

let refused = null;
try {
  const opened = fm.openBytes(readFileSync(file));
  try {
    const info = opened.info();
    const times = opened.keyframeTimes();
    console.log(`${name}: opened: N = ${info.gridN}, ${info.keyframeCount} keyframes over [${info.rangeBegin}, ${info.rangeEnd}] s, ` +
                `texture ${info.textureSize}, ${times.length} times`);
    const decoder = opened.createDecoder();
    try {
      for (const t of timesText.split(',').filter((s) => s !== '').map(Number)) {
        const start = performance.now();
        try {
          if (info.textureSize > 0) decoder.textureWeights(t);
          const frame = decoder.decode(t, 0, { positions: true });
          for (const x of frame.positions) {
            if (!Number.isFinite(x)) throw new Error(`${name}: t = ${t} s: a position is ${x}`);
          }
          console.log(`${name}: t = ${t} s: ${frame.vertexCount} vertices, ${frame.iterations} iterations in ${(performance.now() - start).toFixed(0)} ms`);
        } catch (e) {
          if (!(e instanceof FacemorphError)) throw e;
          refused = refused || e;
          console.log(`${name}: t = ${t} s: refused in ${(performance.now() - start).toFixed(0)} ms: ${e.message}`);
        }
      }
    } finally {
      decoder.destroy();
    }
  } finally {
    opened.close();
  }
} catch (e) {
  if (!(e instanceof FacemorphError)) {
    console.error(`${name}: CRASH: ${e.stack || e}`);
    process.exit(2);
  }
  refused = e;
}
console.log(`${name}: heap ${(fm.heapBytes() / 1048576).toFixed(1)} MiB`);
if (refused) {
  console.error(`${name}: ${refused.message}`);
  process.exit(1);
}
