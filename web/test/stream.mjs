// Streaming under node (spec/web.md §2): FILE served with ranges (web/test/serve.mjs), opened by
// web/stream.js into the module's heap and fm_file_open_memory_borrowed, decoded at COUNT times in
// a shuffled order (seeks both ways) fetching only the groups each frame's keys need, as the worker
// does; every frame must equal the one decoded from the whole file opened by copy, bit for bit.
// Reports what opening and each seek fetched. Exits 1 on a difference.
//   node web/test/stream.mjs FILE.fmv [COUNT=16]
import { readFileSync } from 'node:fs';
import { dirname, join, basename } from 'node:path';
import { fileURLToPath } from 'node:url';
import { loadFacemorph } from '../facemorph_wasm.js';
import { ByteSource, openLayout, ensureKeyframes } from '../stream.js';
import { serve } from './serve.mjs';

// FIRST_REQUEST: the open's first request in bytes (default: the player's); 1 (the preamble alone) makes every chunk the
// open needs come by its own request, not inside the first 4 KiB by chance.
const [file, countText = '16', firstRequestText] = process.argv.slice(2);
const count = Number(countText);
const dist = join(dirname(fileURLToPath(import.meta.url)), '..', 'dist');
const { default: createModule } = await import(join(dist, 'facemorph_wasm.mjs'));
const fm = await loadFacemorph(createModule, readFileSync(join(dist, 'facemorph_wasm.wasm')));

const { server, url, log } = await serve(dirname(file));
let failures = 0;
try {
  const whole = fm.openBytes(readFileSync(file));
  const info = whole.info();
  const reference = whole.createDecoder();

  const source = ByteSource.fromUrl(`${url}/${basename(file)}`);
  const allocate = (size) => fm.allocateFile(size);
  const layout = await openLayout(source, allocate, firstRequestText ? Number(firstRequestText) : undefined);
  const streamed = fm.openBorrowed(source.file);
  const decoder = streamed.createDecoder();
  const times = streamed.keyframeTimes();
  console.log(`${file}: ${source.size} bytes, ${times.length} keyframes in ${layout.groups.length} groups; opening fetched ${source.bytesFetched} bytes in ${source.requests} requests`);
  // Times spread over the range, visited in a fixed shuffled order: the first one the middle, then
  // the end (a seek to the end), then back and forth.
  const ts = Array.from({ length: count }, (_, i) => info.rangeBegin + ((info.rangeEnd - info.rangeBegin) * i) / (count - 1));
  const order = [Math.floor(count / 2), count - 1, ...Array.from({ length: count }, (_, i) => (i * 7) % count)];
  for (const i of order) {
    const t = ts[i];
    const before = source.bytesFetched;
    let k = 0;
    while (k + 1 < times.length && times[k + 1] <= t) ++k;
    await ensureKeyframes(source, layout, k - 3, k + 3, times.length, allocate);
    const a = decoder.decode(t, 0, { positions: true });
    const b = reference.decode(t, 0, { positions: true });
    const same = a.vertexCount === b.vertexCount && a.positions.every((v, j) => Object.is(v, b.positions[j]));
    if (!same) failures += 1;
    if (source.bytesFetched > before || !same) {
      console.log(`${same ? 'ok  ' : 'FAIL'} t = ${t.toFixed(3)} s: fetched ${source.bytesFetched - before} bytes more (keys ${Math.max(0, k - 3)}..${Math.min(times.length - 1, k + 3)})`);
    }
  }
  const sent = log.filter((e) => e.range).reduce((sum, e) => sum + e.bytes, 0);
  console.log(`${failures ? 'FAIL' : 'ok  '} ${order.length} frames streamed equal the whole file's, bit for bit; ${source.bytesFetched} bytes fetched in ` +
              `${source.requests} requests (the server sent ${sent}) of ${source.size}`);
  decoder.destroy();
  streamed.close();
  reference.destroy();
  whole.close();
} finally {
  server.close();
}
process.exit(failures ? 1 : 0);
