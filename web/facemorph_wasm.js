// The C API (facemorph.h, spec/api.md) over the WebAssembly module web/build.sh makes: the same
// functions as the native library, called from JavaScript. Used by the worker (web/worker.js) and by
// the exactness test under node (web/test/exactness.mjs); the page's code uses web/facemorph.js.
//
// Structs are laid out as wasm32 compiles facemorph.h (size_t and pointers 4 bytes, doubles aligned
// to 8); struct_size is set to the 1.0 size, so a later 1.x library serves exactly these fields
// (spec/api.md §3). Every failing call throws a FacemorphError with the status's name and the
// library's message.

const FM_INFO_SIZE = 96;
const FM_FRAME_SIZE = 80;
const FM_OPTIONS_SIZE = 32;  // fm_decoder_options as API 1.2 lays it out (max_work at 24)

export const DecodeFlags = Object.freeze({ clamp: 1, keepHolesFilled: 2, flipV: 4 });

export class FacemorphError extends Error {
  constructor(status, name, message) {
    super(`${name}: ${message}`);
    this.status = status;
    this.statusName = name;
    // What the tools print after the file's name: the library's message less the function's name
    // and the name it gives bytes it is handed ("memory"), e.g. "truncated: chunk TGOP at offset
    // 2928 needs 1571 bytes, only 48 left" (fmdec: "error (truncated): FILE: " and this).
    this.detail = message.replace(/^fm_[a-z0-9_]+: /, '').replace(/^memory: /, '');
  }
}

// Instantiates the module from the .wasm's bytes (fetched by the caller: the page, the worker and
// node load it differently, and emscripten 3.1.6's own loader fails under node 18+, whose fetch
// does not take file paths). `createModule` is the default export of facemorph_wasm.mjs.
export async function loadFacemorph(createModule, wasmBytes) {
  const module = await createModule({ wasmBinary: wasmBytes, print: () => {}, printErr: (text) => console.warn(text) });
  return new Facemorph(module);
}

export class Facemorph {
  constructor(module) {
    this.m = module;
  }

  version() {
    return this.m.UTF8ToString(this.m._fm_version());
  }

  // Bytes the module's heap holds, the decoder's memory (grows, never shrinks: WebAssembly memory).
  heapBytes() {
    return this.m.HEAPU8.length;
  }

  check(status) {
    if (status !== 0) {
      throw new FacemorphError(status, this.m.UTF8ToString(this.m._fm_status_name(status)), this.m.UTF8ToString(this.m._fm_last_error_message()));
    }
  }

  // Opens a file from its bytes, copied into the module (fm_file_open_memory_with_options).
  openBytes(bytes, limits = {}) {
    const size = bytes.byteLength;
    const data = this.m._malloc(Math.max(size, 1));
    this.m.HEAPU8.set(bytes, data);
    try {
      return this.openAt(data, size, limits, false);
    } finally {
      this.m._free(data);
    }
  }

  // A buffer in the module's heap for a file that arrives piece by piece: fill it with
  // buffer.set(bytes, offset), then openBorrowed (fm_file_open_memory_borrowed) once its header,
  // index and chunk headers are there (web/stream.js knows which bytes those are).
  allocateFile(size) {
    return new HeapFile(this, size);
  }

  openBorrowed(heapFile, limits = {}) {
    const file = this.openAt(heapFile.pointer, heapFile.size, limits, true);
    file.heapFile = heapFile;  // the bytes live as long as the file's JS object refers to them
    return file;
  }

  openAt(data, size, limits, borrowed) {
    const m = this.m;
    const options = m._malloc(FM_OPTIONS_SIZE);
    const out = m._malloc(4);
    try {
      m.HEAPU8.fill(0, options, options + FM_OPTIONS_SIZE);
      m.HEAPU32[options >> 2] = FM_OPTIONS_SIZE;
      m.HEAPU32[(options + 4) >> 2] = limits.maxGridN ?? 1025;
      m.HEAPU32[(options + 8) >> 2] = limits.maxKeyframes ?? 65536;
      m.HEAPU32[(options + 12) >> 2] = limits.maxTextureSize ?? 4096;
      const memory = BigInt(limits.maxMemoryBytes ?? 256 * 1024 * 1024);
      new BigUint64Array(m.HEAPU8.buffer, options + 16, 1)[0] = memory;
      // The work of one decode call (spec/container.md §10.3), the caller's or about a second here:
      // a unit is calibrated natively (about 75 ns), and WebAssembly runs about 2.5 times slower
      // (the not-a-knot file of the hostile set: 3.7 s a call in node at the native 16,000,000).
      new BigUint64Array(m.HEAPU8.buffer, options + 24, 1)[0] = BigInt(limits.maxWork ?? 6000000);
      const open = borrowed ? m._fm_file_open_memory_borrowed : m._fm_file_open_memory_with_options;
      this.check(open(data, size, options, out));
      return new File(this, m.HEAPU32[out >> 2]);
    } finally {
      m._free(options);
      m._free(out);
    }
  }
}

class HeapFile {
  constructor(facemorph, size) {
    this.facemorph = facemorph;
    this.size = size;
    this.pointer = facemorph.m._malloc(Math.max(size, 1));
    facemorph.m.HEAPU8.fill(0, this.pointer, this.pointer + size);
  }
  // Views of the heap are remade after every call: the memory may have grown (a new ArrayBuffer).
  set(bytes, offset) {
    if (offset < 0 || offset + bytes.byteLength > this.size) throw new RangeError(`bytes ${offset}..${offset + bytes.byteLength} outside the file's ${this.size}`);
    this.facemorph.m.HEAPU8.set(bytes, this.pointer + offset);
  }
  bytes(offset, length) {
    return this.facemorph.m.HEAPU8.slice(this.pointer + offset, this.pointer + offset + length);
  }
  free() {
    if (this.pointer) this.facemorph.m._free(this.pointer);
    this.pointer = 0;
  }
}

class File {
  constructor(facemorph, handle) {
    this.fm = facemorph;
    this.handle = handle;
  }

  info() {
    const m = this.fm.m;
    const p = m._malloc(FM_INFO_SIZE);
    try {
      m.HEAPU8.fill(0, p, p + FM_INFO_SIZE);
      m.HEAPU32[p >> 2] = FM_INFO_SIZE;
      this.fm.check(m._fm_file_get_info(this.handle, p));
      const f64 = (o) => m.HEAPF64[(p + o) >> 3];
      const u32 = (o) => m.HEAPU32[(p + o) >> 2];
      return {
        fps: f64(8), firstTime: f64(16), lastTime: f64(24), duration: f64(32), rangeBegin: f64(40), rangeEnd: f64(48),
        keyframeCount: u32(56), gridN: u32(60), maxVertexCount: u32(64), maxTriangleCount: u32(68),
        gridVertexCount: u32(72), gridTriangleCount: u32(76), hasHoles: u32(80) !== 0, textureSize: u32(84),
        units: m.UTF8ToString(p + 88, 8),
      };
    } finally {
      m._free(p);
    }
  }

  keyframeTimes() {
    const m = this.fm.m;
    const countPointer = m._malloc(4);
    try {
      this.fm.check(m._fm_file_get_keyframe_times(this.handle, 0, 0, countPointer));
      const count = m.HEAPU32[countPointer >> 2];
      const times = m._malloc(8 * Math.max(count, 1));
      try {
        this.fm.check(m._fm_file_get_keyframe_times(this.handle, times, count, countPointer));
        return Array.from(m.HEAPF64.subarray(times >> 3, (times >> 3) + count));
      } finally {
        m._free(times);
      }
    } finally {
      m._free(countPointer);
    }
  }

  createDecoder() {
    const m = this.fm.m;
    const out = m._malloc(4);
    try {
      this.fm.check(m._fm_decoder_create(this.handle, out));
      return new Decoder(this.fm, m.HEAPU32[out >> 2], this.info());
    } finally {
      m._free(out);
    }
  }

  close() {
    if (this.handle) this.fm.m._fm_file_close(this.handle);
    this.handle = 0;
  }
}

class Decoder {
  constructor(facemorph, handle, info) {
    this.fm = facemorph;
    this.handle = handle;
    this.info = info;
    const m = facemorph.m;
    // The frame's buffers, sized once for every frame of the file (fm_info's bounds).
    this.frame = m._malloc(FM_FRAME_SIZE);
    this.positions = m._malloc(12 * info.maxVertexCount);
    this.normals = m._malloc(12 * info.maxVertexCount);
    this.uvs = m._malloc(8 * info.maxVertexCount);
    this.indices = m._malloc(12 * info.maxTriangleCount);
    this.weightKeys = m._malloc(4 * 128);
    this.weightValues = m._malloc(8 * 128);
    this.weightCount = m._malloc(4);
  }

  // The frame at t: {time, vertexCount, triangleCount, iterations, fellBack} and fresh typed arrays
  // (copies out of the heap, so they may be transferred to another thread) for what `want` names:
  // positions, normals, uvs, indices (all by default).
  decode(t, flags = 0, want = { positions: true, normals: true, uvs: true, indices: true }) {
    const m = this.fm.m;
    const f = this.frame;
    m.HEAPU8.fill(0, f, f + FM_FRAME_SIZE);
    m.HEAPU32[f >> 2] = FM_FRAME_SIZE;
    const set = (offset, pointer, bytes) => {
      m.HEAPU32[(f + offset) >> 2] = pointer;
      m.HEAPU32[(f + offset + 4) >> 2] = bytes;
    };
    if (want.positions) set(4, this.positions, 12 * this.info.maxVertexCount);
    if (want.normals) set(12, this.normals, 12 * this.info.maxVertexCount);
    if (want.uvs) set(20, this.uvs, 8 * this.info.maxVertexCount);
    if (want.indices) set(28, this.indices, 12 * this.info.maxTriangleCount);
    this.fm.check(m._fm_decoder_decode(this.handle, t, flags, f));
    const vertexCount = m.HEAPU32[(f + 56) >> 2];
    const triangleCount = m.HEAPU32[(f + 60) >> 2];
    const floats = (pointer, n) => m.HEAPF32.slice(pointer >> 2, (pointer >> 2) + n);
    return {
      time: m.HEAPF64[(f + 48) >> 3],
      vertexCount,
      triangleCount,
      iterations: m.HEAPU32[(f + 68) >> 2],
      fellBack: m.HEAPU32[(f + 72) >> 2] !== 0,
      positions: want.positions ? floats(this.positions, 3 * vertexCount) : null,
      normals: want.normals ? floats(this.normals, 3 * vertexCount) : null,
      uvs: want.uvs ? floats(this.uvs, 2 * vertexCount) : null,
      indices: want.indices ? m.HEAPU32.slice(this.indices >> 2, (this.indices >> 2) + 3 * triangleCount) : null,
    };
  }

  // The texture blend at t (fm_decoder_get_texture_weights, API 1.1): [{keyframe, weight}], the
  // weights as the native blend takes them (float).
  textureWeights(t, flags = 0) {
    const m = this.fm.m;
    this.fm.check(m._fm_decoder_get_texture_weights(this.handle, t, flags, this.weightKeys, this.weightValues, 128, this.weightCount));
    const count = m.HEAPU32[this.weightCount >> 2];
    const out = [];
    for (let i = 0; i < count; ++i) {
      out.push({ keyframe: m.HEAPU32[(this.weightKeys >> 2) + i], weight: Math.fround(m.HEAPF64[(this.weightValues >> 3) + i]) });
    }
    return out;
  }

  destroy() {
    const m = this.fm.m;
    if (!this.handle) return;
    m._fm_decoder_destroy(this.handle);
    for (const p of [this.frame, this.positions, this.normals, this.uvs, this.indices, this.weightKeys, this.weightValues, this.weightCount]) m._free(p);
    this.handle = 0;
  }
}
