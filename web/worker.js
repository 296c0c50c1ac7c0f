// The decoding thread of web/facemorph.js: the WebAssembly decoder, the file's bytes as they stream
// in, and the keyframes' texture images, so that the page's thread only uploads what it is sent.
//
// Messages in:  {type: 'open', id, url | bytes, wasmUrl, moduleUrl, limits}
//               {type: 'decode', id, t, flags, haveTextures: [keyframe...], wantTexture}
// Messages out: {type: 'reply', id, result} or {type: 'error', id, message, status}
// A decode's result carries fresh typed arrays (transferred), the texture blend's weights, and the
// images of the keyframes it needs that the page does not hold yet (ImageBitmaps, transferred).
import { loadFacemorph, DecodeFlags } from './facemorph_wasm.js';
import { ByteSource, openLayout, ensureKeyframes, textureOf } from './stream.js';

let fm = null;
let state = null;  // {source, layout, file, decoder, info, times, complete}

async function loadModule(moduleUrl, wasmUrl) {
  if (fm) return fm;
  const [{ default: createModule }, wasm] = await Promise.all([
    import(moduleUrl),
    fetch(wasmUrl).then((r) => {
      if (!r.ok) throw new Error(`${wasmUrl}: HTTP ${r.status}`);
      return r.arrayBuffer();
    }),
  ]);
  fm = await loadFacemorph(createModule, new Uint8Array(wasm));
  return fm;
}

function close() {
  if (!state) return;
  state.decoder?.destroy();
  state.file?.close();
  state.source.file?.free();
  for (const decoder of state.imageDecoders.values()) decoder.close?.();
  state = null;
}

async function open(message) {
  await loadModule(message.moduleUrl, message.wasmUrl);
  close();
  const source = message.bytes ? ByteSource.fromBytes(new Uint8Array(message.bytes)) : ByteSource.fromUrl(message.url);
  const allocate = (size) => fm.allocateFile(size);
  const started = performance.now();
  const layout = await openLayout(source, allocate);
  const file = fm.openBorrowed(source.file, message.limits || {});
  const info = file.info();
  const times = file.keyframeTimes();
  const decoder = file.createDecoder();
  state = { source, layout, file, decoder, info, times, allocate, limits: message.limits || {}, imageDecoders: new Map(), complete: false };
  return {
    info, keyframeTimes: times, version: fm.version(), groups: layout.groups.length,
    bytesFetched: source.bytesFetched, requests: source.requests, fileBytes: source.size, openMs: performance.now() - started,
  };
}

// The keyframes the frame at t blends are among i - 3 .. i + 3 around t's segment (every local
// spline of spec/method.md §7 blends at most 6 around it); their groups are fetched first.
function keyframeWindow(t) {
  const times = state.times;
  let i = 0;
  while (i + 1 < times.length && times[i + 1] <= t) ++i;
  return [i - 3, i + 3];
}

// Every group: what a global spline (not-a-knot) may need, and the way out after a decode that read
// a group before its bytes were there (a remembered fault): reopened over the complete bytes.
async function completeAndReopen() {
  const { source, layout, allocate } = state;
  await ensureKeyframes(source, layout, 0, state.times.length - 1, state.times.length, allocate);
  state.decoder.destroy();
  state.file.close();
  state.file = fm.openBorrowed(source.file, state.limits);
  state.decoder = state.file.createDecoder();
  state.complete = true;
}

// Keyframe k's image as an ImageBitmap (transferred to the page, so not kept here: the page keeps
// what it holds and says so in haveTextures).
async function decodeImage(k) {
  const where = textureOf(state.layout, k);
  if (!where) throw new Error(`keyframe ${k} has no texture chunk`);
  await state.source.ensure(where.begin, where.end, state.allocate);
  const bytes = state.source.file.bytes(where.begin, where.end - where.begin);
  let bitmap;
  if (where.codec === 3) {
    // One AVIF image sequence per group (format 2.1): frame k - gP of it. WebCodecs' ImageDecoder
    // decodes any frame; without it (an older browser) createImageBitmap gives the first frame only.
    if (typeof ImageDecoder !== 'undefined') {
      let decoder = state.imageDecoders.get(where.chunk.offset);
      if (!decoder) {
        decoder = new ImageDecoder({ data: bytes, type: 'image/avif' });
        state.imageDecoders.set(where.chunk.offset, decoder);
      }
      const { image } = await decoder.decode({ frameIndex: where.frame });
      bitmap = await createImageBitmap(image);
      image.close();
    } else {
      bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/avif' }));
    }
  } else {
    bitmap = await createImageBitmap(new Blob([bytes], { type: where.codec === 1 ? 'image/webp' : 'image/avif' }));
  }
  return bitmap;
}

async function decode(message) {
  if (!state) throw new Error('no file is open');
  const flags = message.flags ?? 0;
  const t = (flags & DecodeFlags.clamp) ? Math.min(Math.max(message.t, state.info.rangeBegin), state.info.rangeEnd) : message.t;
  const fetchedBefore = state.source.bytesFetched;
  if (!state.complete) {
    const [from, to] = keyframeWindow(t);
    await ensureKeyframes(state.source, state.layout, from, to, state.times.length, state.allocate);
  }
  const started = performance.now();
  let frame;
  try {
    frame = state.decoder.decode(t, flags);
  } catch (error) {
    if (state.complete || error.statusName !== 'corrupt') throw error;
    await completeAndReopen();
    frame = state.decoder.decode(t, flags);
  }
  const decodeMs = performance.now() - started;
  const weights = state.info.textureSize > 0 ? state.decoder.textureWeights(t, flags).filter((w) => w.weight !== 0) : [];
  const textures = [];
  if (message.wantTexture !== false) {
    const have = new Set(message.haveTextures || []);
    for (const { keyframe } of weights) {
      if (!have.has(keyframe)) textures.push({ keyframe, bitmap: await decodeImage(keyframe) });
    }
  }
  const result = {
    ...frame, weights, textures, decodeMs,
    bytesFetched: state.source.bytesFetched, fetchedNow: state.source.bytesFetched - fetchedBefore, requests: state.source.requests,
    heapBytes: fm.heapBytes(),
  };
  const transfer = [frame.positions, frame.normals, frame.uvs, frame.indices].filter(Boolean).map((a) => a.buffer);
  for (const texture of textures) transfer.push(texture.bitmap);
  return { result, transfer };
}

self.onmessage = async (event) => {
  const message = event.data;
  try {
    if (message.type === 'open') {
      self.postMessage({ type: 'reply', id: message.id, result: await open(message) });
    } else if (message.type === 'decode') {
      const { result, transfer } = await decode(message);
      self.postMessage({ type: 'reply', id: message.id, result }, transfer);
    } else if (message.type === 'close') {
      close();
      self.postMessage({ type: 'reply', id: message.id, result: null });
    }
  } catch (error) {
    self.postMessage({ type: 'error', id: message.id, message: String(error.message || error), status: error.statusName || null });
  }
};
