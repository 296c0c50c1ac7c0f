// A .fmv file as it arrives over HTTP range requests (spec/web.md §2): the bytes the decoder reads
// at open first (the preamble, the HEAD and KIDX chunks, every other chunk's 24-byte header and
// 4-byte checksum), then each keyframe group's chunks when a frame needs them. The bytes live in
// the WebAssembly module's heap (a HeapFile), which the decoder reads where they lie
// (fm_file_open_memory_borrowed, API 1.1): a range is copied in once, when it arrives.
//
// The chunk walk reads only the chunk framing of spec/container.md §3 (type, flags, sizes, checksum)
// and the first two numbers of a group's payload (its first keyframe, its image codec): everything
// else, and every check of it, is the decoder's. A server that ignores Range (200 and the whole
// body) is served too: the file is then simply all there.

const PREAMBLE = 16, HEADER = 24, TRAILER = 4;
const FIRST_REQUEST = 4096;  // the preamble, HEAD and KIDX of a small file in one round trip; a larger header costs one more

// Ranges [begin, end) held, merged.
class RangeSet {
  constructor() { this.ranges = []; }
  add(begin, end) {
    const merged = [];
    for (const [b, e] of this.ranges) {
      if (e < begin || b > end) merged.push([b, e]);
      else { begin = Math.min(begin, b); end = Math.max(end, e); }
    }
    merged.push([begin, end]);
    merged.sort((x, y) => x[0] - y[0]);
    this.ranges = merged;
  }
  has(begin, end) {
    return end <= begin || this.ranges.some(([b, e]) => b <= begin && end <= e);
  }
}

export class ByteSource {
  // fetchRange(begin, end) -> Promise<{bytes: Uint8Array, begin, total}>: what a transport gives.
  constructor(fetchRange) {
    this.fetchRange = fetchRange;
    this.held = new RangeSet();
    this.file = null;   // HeapFile once the size is known
    this.size = 0;
    this.bytesFetched = 0;
    this.requests = 0;
  }

  static fromUrl(url, fetchImpl = fetch) {
    return new ByteSource(async (begin, end) => {
      const response = await fetchImpl(url, { headers: { Range: `bytes=${begin}-${end - 1}` } });
      if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
      const bytes = new Uint8Array(await response.arrayBuffer());
      if (response.status === 206) {
        const match = /bytes (\d+)-(\d+)\/(\d+)/.exec(response.headers.get('Content-Range') || '');
        if (!match) throw new Error(`${url}: a 206 response without a Content-Range`);
        return { bytes, begin: Number(match[1]), total: Number(match[3]) };
      }
      return { bytes, begin: 0, total: bytes.length };  // no range support: the whole file
    });
  }

  static fromBytes(all) {
    return new ByteSource(async (begin, end) => ({ bytes: all.subarray(begin, Math.min(end, all.length)), begin, total: all.length }));
  }

  // Makes [begin, end) present (clipped to the file), fetching what is missing as one range.
  async ensure(begin, end, allocate) {
    if (this.file) {
      end = Math.min(end, this.size);
      // Only what is missing: a held head or tail of the range is not fetched again.
      for (const [b, e] of this.held.ranges) if (b <= begin && begin < e) begin = e;
      for (const [b, e] of this.held.ranges) if (b < end && end <= e) end = b;
      if (end <= begin) return;
    }
    const got = await this.fetchRange(begin, end);
    this.requests += 1;
    this.bytesFetched += got.bytes.length;
    if (!this.file) {
      this.size = got.total;
      this.file = allocate(got.total);
    }
    if (got.begin + got.bytes.length > this.size) throw new Error('the server sent bytes past the end of the file');
    this.file.set(got.bytes, got.begin);
    this.held.add(got.begin, got.begin + got.bytes.length);
  }

  u32(offset) {
    const b = this.file.bytes(offset, 4);
    return (b[0] | (b[1] << 8) | (b[2] << 16) | (b[3] << 24)) >>> 0;
  }
  u64(offset) {
    return this.u32(offset) + this.u32(offset + 4) * 2 ** 32;
  }
}

// Walks the chunks (one request per chunk not already held: its trailer and the next header come
// together) and returns the layout: groups[g] = {first, kgop: {offset, size}, texture: {...}}.
// firstRequest: bytes asked for at once, the preamble at least (tests ask for no more, so that no
// chunk arrives by chance).
export async function openLayout(source, allocate, firstRequest = FIRST_REQUEST) {
  await source.ensure(0, Math.max(firstRequest, PREAMBLE), allocate);
  const chunks = [];
  let offset = PREAMBLE;
  for (;;) {
    await source.ensure(offset, offset + HEADER + 8, allocate);
    const type = String.fromCharCode(...source.file.bytes(offset, 4));
    const stored = source.u64(offset + 8);
    if (!/^[A-Z0-9]{4}$/.test(type) || offset + HEADER + stored + TRAILER > source.size) {
      throw new Error(`not a facemorph file, or a damaged one: chunk at ${offset}`);
    }
    const chunk = { type, offset, payload: offset + HEADER, stored, end: offset + HEADER + stored + TRAILER };
    // A keyframe group's chunks (KGOP, or 2.6's KGLV; TGOP, TEXR) are fetched when a frame needs them: of these, the
    // framing and first numbers now. Every other chunk whole, as the open reads it: the header, the
    // index, 2.3's residual frames (RSDW, read at open), the end, and chunks of later minors.
    const inGroup = type === 'KGOP' || type === 'KGLV' || type === 'TGOP' || type === 'TEXR';
    if (!inGroup) await source.ensure(offset, chunk.end, allocate);
    else await source.ensure(chunk.end - TRAILER, chunk.end + HEADER + 8, allocate);
    if (stored >= 8 && inGroup) {
      chunk.first = source.u32(chunk.payload);
      chunk.codec = source.u32(chunk.payload + 4);
    }
    chunks.push(chunk);
    if (type === 'FEND') break;
    offset = chunk.end;
  }
  const groups = [];
  for (const chunk of chunks) {
    if (chunk.type === 'KGOP' || chunk.type === 'KGLV') groups.push({ first: chunk.first, kgop: chunk, textures: [] });
    else if ((chunk.type === 'TGOP' || chunk.type === 'TEXR') && groups.length) groups[groups.length - 1].textures.push(chunk);
  }
  return { chunks, groups };
}

// The group holding keyframe k (groups are in keyframe order).
export function groupOf(layout, k) {
  let found = null;
  for (const group of layout.groups) if (group.first <= k) found = group;
  return found;
}

// Where keyframe k's texture image is: {bytes: [begin, end), codec (1 WebP, 2 AVIF, 3 AVIF
// sequence), frame: its index in the sequence, group}.
export function textureOf(layout, k) {
  const group = groupOf(layout, k);
  if (!group) return null;
  for (const chunk of group.textures) {
    const image = { begin: chunk.payload + 8, end: chunk.payload + chunk.stored, codec: chunk.codec, chunk };
    if (chunk.type === 'TGOP') return { ...image, frame: k - chunk.first, group };
    if (chunk.type === 'TEXR' && chunk.first === k) return { ...image, frame: 0, group };
  }
  return null;
}

// Fetches the chunks of the groups holding keyframes [from, to] (clipped), one request per group.
export async function ensureKeyframes(source, layout, from, to, count, allocate) {
  const lo = Math.max(0, from), hi = Math.min(count - 1, to);
  const groups = new Set();
  for (let k = lo; k <= hi; ++k) groups.add(groupOf(layout, k));
  for (const group of groups) {
    if (!group) continue;
    const last = group.textures.length ? group.textures[group.textures.length - 1].end : group.kgop.end;
    await source.ensure(group.kgop.offset, last, allocate);
  }
}
