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
let fileName = '';  // what errors call the file being opened or played

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

// The decoder's own verdict on bytes the chunk walk refused (a PNG, a truncated or damaged file):
// the C API opened over what has arrived, which the walk fetched up to the chunk it refused, so the
// page names the error as fmdec and fminfo do ('truncated', 'corrupt', with the library's message)
// rather than the walk's. Should the decoder take the bytes, the walk's error stands.
function nativeVerdict(source, walkError, limits) {
  if (!source.file) return walkError;  // nothing arrived: the transport's error (an HTTP status)
  try {
    fm.openBorrowed(source.file, limits).close();
    return walkError;
  } catch (error) {
    return error;
  } finally {
    source.file.free();
  }
}

async function open(message) {
  await loadModule(message.moduleUrl, message.wasmUrl);
  close();
  fileName = message.name || message.url || 'the bytes given';
  const source = message.bytes ? ByteSource.fromBytes(new Uint8Array(message.bytes)) : ByteSource.fromUrl(message.url);
  const allocate = (size) => fm.allocateFile(size);
  const started = performance.now();
  let layout;
  try {
    layout = await openLayout(source, allocate);
  } catch (error) {
    throw nativeVerdict(source, error, message.limits || {});
  }
  let file;
  try {
    file = fm.openBorrowed(source.file, message.limits || {});
  } catch (error) {
    source.file.free();
    throw error;
  }
  const info = file.info();
  const times = file.keyframeTimes();
  const decoder = file.createDecoder();
  state = { source, layout, file, decoder, info, times, allocate, limits: message.limits || {}, imageDecoders: new Map(), complete: false };
  return {
    info, keyframeTimes: times, version: fm.version(), groups: layout.groups.length,
    // Each group's first keyframe and its bytes [begin, end): its KGOP through its texture chunks.
    groupRanges: layout.groups.map((g) => ({ first: g.first, begin: g.kgop.offset, end: g.textures.length ? g.textures[g.textures.length - 1].end : g.kgop.end })),
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

// The texels as the file codes them, converted to RGB by the matrix and range it signals and
// nothing more: no colour management to the display's space, which the native decoder does not do
// either (measured without it: 2-3% brighter than fmdec --preview).
const noConversion = { colorSpaceConversion: 'none', premultiplyAlpha: 'none' };

// Chromium (156) converts the frames of an AVIF image sequence (format 2.1's TGOP) as if they were
// limited range, where fmenc writes full-range BT.601 (spec/container.md §8) and libavif reads them
// so: every texel comes out as M·S·(Y − 16, U, V), S = diag(255/219, 255/224, 255/224), not M·(Y, U, V)
// (measured on the README's sample: 0.37 of a unit from that model, 3.9 from limited BT.709, 9.5
// from full BT.709); AVIF stills it converts right. Whether this browser does so is found once per
// kind from a 16 × 16 grey of 200 that facemorph's own encoders wrote (encode_avif_sequence and
// encode_avif, quality 90, the textures' settings): 200 back, or 214 where the range was taken as
// limited. The page then applies the inverse, RGB = M·S⁻¹·M⁻¹·RGB' + 16/255, in its shader (texels
// the browser clipped at 0 or 255 stay clipped).
const CALIBRATION = {
  sequence: 'AAAALGZ0eXBhdmlzAAAAAGF2aWZhdmlzbXNmMWlzbzhtaWYxbWlhZk1BMUEAAADybWV0YQAAAAAAAAAoaGRscgAAAAAAAAAAcGljdAAAAAAAAAAAAAAAAGxpYmF2aWYAAAAADnBpdG0AAAAAAAEAAAAeaWxvYwAAAABEAAABAAEAAAABAAADxwAAACAAAAAoaWluZgAAAAAAAQAAABppbmZlAgAAAAABAABhdjAxQ29sb3IAAAAAamlwcnAAAABLaXBjbwAAABRpc3BlAAAAAAAAABAAAAAQAAAAEHBpeGkAAAAAAwgICAAAAAxhdjFDgSAAAAAAABNjb2xybmNseAACAAIABoAAAAAXaXBtYQAAAAAAAAABAAEEAQKDBAAAAqFtb292AAAAeG12aGQBAAAAAAAAAAAAAAAAAAAAAAAAAAAAAB4AAAAAAAAAAgABAAABAAAAAAAAAAAAAAAAAQAAAAAAAAAAAAAAAAAAAAEAAAAAAAAAAAAAAAAAAEAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAABAAACIXRyYWsAAABodGtoZAEAAAEAAAAAAAAAAAAAAAAAAAAAAAAAAQAAAAAAAAAAAAAAAgAAAAAAAAAAAAAAAAAAAAAAAQAAAAAAAAAAAAAAAAAAAAEAAAAAAAAAAAAAAAAAAEAAAAAAEAAAABAAAAAAAbFtZGlhAAAALG1kaGQBAAAAAAAAAAAAAAAAAAAAAAAAAAAAAB4AAAAAAAAAAlXEAAAAAAAoaGRscgAAAAAAAAAAcGljdAAAAAAAAAAAAAAAAGxpYmF2aWYAAAABVW1pbmYAAAAUdm1oZAAAAAEAAAAAAAAAAAAAACRkaW5mAAAAHGRyZWYAAAAAAAAAAQAAAAx1cmwgAAAAAQAAARVzdGJsAAAAFHN0Y28AAAAAAAAAAQAAA8cAAAAcc3RzYwAAAAAAAAABAAAAAQAAAAIAAAABAAAAHHN0c3oAAAAAAAAAAAAAAAIAAAAgAAAAFQAAABRzdHNzAAAAAAAAAAEAAAABAAAAGHN0dHMAAAAAAAAAAQAAAAIAAAABAAAAlXN0c2QAAAAAAAAAAQAAAIVhdjAxAAAAAAAAAAEAAAAAAAAAAAAAAAAAAAAAABAAEABIAAAASAAAAAAAAAABCkFPTSBDb2RpbmcAAAAAAAAAAAAAAAAAAAAAAAAAAAAAGP//AAAADGF2MUOBIAAAAAAAE2NvbHJuY2x4AAIAAgAGgAAAABBjY3N0AAAAAHwAAAAAAAA9bWRhdBIACgwgAAABn/m18kCAgaQyDhAAjAAAAgAAAABXrfgNEgAyETADwIAAAEaMAAACAAAgAHaQ',
  still: 'AAAAIGZ0eXBhdmlmAAAAAGF2aWZtaWYxbWlhZk1BMUEAAADybWV0YQAAAAAAAAAoaGRscgAAAAAAAAAAcGljdAAAAAAAAAAAAAAAAGxpYmF2aWYAAAAADnBpdG0AAAAAAAEAAAAeaWxvYwAAAABEAAABAAEAAAABAAABGgAAABgAAAAoaWluZgAAAAAAAQAAABppbmZlAgAAAAABAABhdjAxQ29sb3IAAAAAamlwcnAAAABLaXBjbwAAABRpc3BlAAAAAAAAABAAAAAQAAAAEHBpeGkAAAAAAwgICAAAAAxhdjFDgSAAAAAAABNjb2xybmNseAACAAIABoAAAAAXaXBtYQAAAAAAAAABAAEEAQKDBAAAACBtZGF0EgAKCDgM/9hAgIGkMgoRgAAAQABXrfgN',
};
const corrections = new Map();
async function calibrationGrey(kind) {
  const bytes = Uint8Array.from(atob(CALIBRATION[kind]), (c) => c.charCodeAt(0));
  let bitmap;
  if (kind === 'sequence' && typeof ImageDecoder !== 'undefined') {
    const decoder = new ImageDecoder({ data: bytes, type: 'image/avif', colorSpaceConversion: 'none' });
    const { image } = await decoder.decode({ frameIndex: 0 });
    bitmap = await createImageBitmap(image, noConversion);
    image.close();
    decoder.close();
  } else {
    bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/avif' }), noConversion);
  }
  const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
  const context = canvas.getContext('2d');
  context.drawImage(bitmap, 0, 0);
  const grey = context.getImageData(8, 8, 1, 1).data[1];
  bitmap.close();
  return grey;
}
// The correction for images of `kind` ('sequence', 'still' or 'webp'): {matrix (column-major mat3)
// or null, offset, grey}.
async function textureCorrection(kind) {
  if (kind === 'webp') return { matrix: null, grey: null };  // no YUV range to take wrongly
  if (corrections.has(kind)) return corrections.get(kind);
  const grey = await calibrationGrey(kind);
  let correction = { matrix: null, grey };
  if (grey >= 207) {
    // M: BT.601 Y'CbCr to R'G'B' (chroma centred); A = M·S⁻¹·M⁻¹, column-major for a GLSL mat3.
    const M = [[1, 0, 1.402], [1, -0.344136, -0.714136], [1, 1.772, 0]];
    const inverse = (m) => {
      const [a, b, c] = m[0], [d, e, f] = m[1], [g, h, i] = m[2];
      const det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
      return [[(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det],
              [(f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det],
              [(d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det]];
    };
    const multiply = (x, y) => x.map((row) => y[0].map((_, j) => row.reduce((sum, v, k) => sum + v * y[k][j], 0)));
    const scale = [[219 / 255, 0, 0], [0, 224 / 255, 0], [0, 0, 224 / 255]];
    const A = multiply(multiply(M, scale), inverse(M));
    correction = { matrix: [A[0][0], A[1][0], A[2][0], A[0][1], A[1][1], A[2][1], A[0][2], A[1][2], A[2][2]], offset: 16 / 255, grey };
  }
  corrections.set(kind, correction);
  return correction;
}

// Keyframe k's image as {bitmap (an ImageBitmap, transferred to the page, so not kept here: the
// page keeps what it holds and says so in haveTextures), correction (textureCorrection's, or null)}.
// A TGOP of one keyframe is a still AVIF (libavif writes a one-frame sequence so): its brand says.
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
        decoder = new ImageDecoder({ data: bytes, type: 'image/avif', colorSpaceConversion: 'none' });
        state.imageDecoders.set(where.chunk.offset, decoder);
      }
      const { image } = await decoder.decode({ frameIndex: where.frame });
      bitmap = await createImageBitmap(image, noConversion);
      image.close();
    } else {
      bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/avif' }), noConversion);
    }
  } else {
    bitmap = await createImageBitmap(new Blob([bytes], { type: where.codec === 1 ? 'image/webp' : 'image/avif' }), noConversion);
  }
  const brand = String.fromCharCode(...bytes.subarray(8, 12));  // the ftyp box's major brand
  const kind = where.codec === 1 ? 'webp' : where.codec === 3 && brand === 'avis' ? 'sequence' : 'still';
  const correction = await textureCorrection(kind);
  return { bitmap, correction: correction.matrix ? correction : null };
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
      if (!have.has(keyframe)) textures.push({ keyframe, ...(await decodeImage(keyframe)) });
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
    // The decoder's errors read as fmdec's: "error (STATUS): FILE: what the library says".
    const text = error.detail !== undefined ? `error (${error.statusName}): ${fileName}: ${error.detail}` : String(error.message || error);
    self.postMessage({ type: 'error', id: message.id, message: text, status: error.statusName || null });
  }
};
