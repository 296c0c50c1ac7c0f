// A compact glTF clip (fmdec -o CLIP.glb: KHR_mesh_quantization + EXT_meshopt_compression) against
// the same clip in floats (fmdec --glb-float): the Khronos validator finds no error in either (it
// cannot look inside meshopt's streams, and says so), every compressed stream decodes with the
// decoder three.js uses (MeshoptDecoder), and every frame's positions, dequantised by the node's
// transform, are the float clip's within half a quantisation step per coordinate; the indices are
// the same and the UVs within one unit of 16 bits. Normals (issue 48 part 4): the float clip's are
// the decoder's rule (area-weighted over the clip's triangles, recomputed here from its positions),
// the compact clip's base normals are normalised int8 of unit length (within 0.005, under the
// validator's 0.00674), and every frame's normal there (base plus its morph target's difference)
// is the float clip's within 1/127 a component. Prints both sizes.
//   node web/test/gltf_check.mjs COMPACT.glb FLOAT.glb
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const root = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const npm = resolve(root, process.env.FACEMORPH_NPM_DIR || 'build-web/npm');
let validator, MeshoptDecoder;
try {
  validator = createRequire(join(npm, 'package.json'))('gltf-validator');
  ({ MeshoptDecoder } = await import(pathToFileURL(join(npm, 'node_modules/three/examples/jsm/libs/meshopt_decoder.module.js')).href));
} catch {
  console.log(`SKIPPED: gltf-validator or three not found in ${npm} (web/install-npm.sh installs them)`);
  process.exit(77);
}
const [compactPath, floatPath] = process.argv.slice(2);

function parse(path) {
  const bytes = new Uint8Array(readFileSync(path));
  const view = new DataView(bytes.buffer);
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const binLength = view.getUint32(20 + jsonLength, true);
  const bin = bytes.subarray(28 + jsonLength, 28 + jsonLength + binLength);
  return { bytes, json, buffers: [bin, new Uint8Array(json.buffers[1]?.byteLength || 0)] };
}

let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) failures += 1;
};

const compact = parse(compactPath), plain = parse(floatPath);
for (const [name, glb] of [['compact', compact], ['float', plain]]) {
  const report = await validator.validateBytes(glb.bytes);
  const errors = report.issues.messages.filter((m) => m.severity === 0);
  check(errors.length === 0, `${name} clip: the Khronos validator finds ${errors.length} errors${errors.length ? ': ' + JSON.stringify(errors.slice(0, 3)) : ''}`);
}

// Decode every compressed view into the fallback buffer, where the accessors read it.
await MeshoptDecoder.ready;
for (const view of compact.json.bufferViews) {
  const ext = view.extensions?.EXT_meshopt_compression;
  if (!ext) continue;
  const source = compact.buffers[ext.buffer].subarray(ext.byteOffset, ext.byteOffset + ext.byteLength);
  const target = new Uint8Array(ext.count * ext.byteStride);
  MeshoptDecoder.decodeGltfBuffer(target, ext.count, ext.byteStride, source, ext.mode, ext.filter || 'NONE');
  compact.buffers[view.buffer].set(target, view.byteOffset || 0);
}

function read(glb, index) {
  const accessor = glb.json.accessors[index];
  const view = glb.json.bufferViews[accessor.bufferView];
  const buffer = glb.buffers[view.buffer];
  const components = { SCALAR: 1, VEC2: 2, VEC3: 3 }[accessor.type];
  const Type = { 5126: Float32Array, 5125: Uint32Array, 5123: Uint16Array, 5122: Int16Array, 5120: Int8Array }[accessor.componentType];
  const stride = (view.byteStride || components * Type.BYTES_PER_ELEMENT) / Type.BYTES_PER_ELEMENT;
  const all = new Type(buffer.buffer.slice(buffer.byteOffset + (view.byteOffset || 0) + (accessor.byteOffset || 0), buffer.byteOffset + (view.byteOffset || 0) + view.byteLength));
  const out = new Float64Array(accessor.count * components);
  for (let i = 0; i < accessor.count; ++i) for (let k = 0; k < components; ++k) out[i * components + k] = all[i * stride + k];
  return out;
}

const pc = compact.json.meshes[0].primitives[0], pf = plain.json.meshes[0].primitives[0];
const node = compact.json.nodes[0];
const step = node.scale[0];
const basePlain = read(plain, pf.attributes.POSITION), baseCodes = read(compact, pc.attributes.POSITION);
let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
for (let i = 0; i < basePlain.length; ++i) { lo[i % 3] = Math.min(lo[i % 3], basePlain[i]); hi[i % 3] = Math.max(hi[i % 3], basePlain[i]); }
const diagonal = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
let worst = 0;
check(pc.targets.length === pf.targets.length, `${pc.targets.length} morph targets in both`);
for (let f = 0; f <= pf.targets.length; ++f) {
  const dp = f ? read(plain, pf.targets[f - 1].POSITION) : null, dc = f ? read(compact, pc.targets[f - 1].POSITION) : null;
  for (let i = 0; i < basePlain.length; ++i) {
    const exact = basePlain[i] + (f ? dp[i] : 0);
    const decoded = node.translation[i % 3] + step * (baseCodes[i] + (f ? dc[i] : 0));
    worst = Math.max(worst, Math.abs(decoded - exact));
  }
}
// Half a step, and the float clip's own float32 rounding (its differences are float32 too).
check(worst <= 0.5 * step + 1e-6 * diagonal, `positions of all ${pf.targets.length + 1} frames within half a step: worst ${worst.toExponential(3)} ` +
      `(step ${step.toExponential(3)}, ${(worst / diagonal).toExponential(2)} of the diagonal)`);
// meshoptimizer's index codec may rotate a triangle's corners (its winding kept): compared so.
const rotated = (a) => {
  const out = [];
  for (let i = 0; i < a.length; i += 3) {
    const t = [a[i], a[i + 1], a[i + 2]];
    const m = t.indexOf(Math.min(...t));
    out.push(`${t[m]},${t[(m + 1) % 3]},${t[(m + 2) % 3]}`);
  }
  return out;
};
const ic = rotated(read(compact, pc.indices)), ip = rotated(read(plain, pf.indices));
check(ic.length === ip.length && ic.every((v, i) => v === ip[i]), `the same ${ic.length} triangles, in order, wound the same way`);
if (pf.attributes.TEXCOORD_0 !== undefined) {
  const uc = read(compact, pc.attributes.TEXCOORD_0), up = read(plain, pf.attributes.TEXCOORD_0);
  let uvWorst = 0;
  for (let i = 0; i < up.length; ++i) uvWorst = Math.max(uvWorst, Math.abs(uc[i] / 65535 - up[i]));
  check(uvWorst <= 1 / 65535, `UVs within one unit of 16 bits (worst ${uvWorst.toExponential(2)})`);
}
// Normals. Frame f's in a clip: the base's plus target f's difference (what a viewer sums before
// normalising); a normalised accessor's codes read as glTF 2.0 §3.11 says (int8: c / 127).
const normalised = (glb, index) => {
  const values = read(glb, index), accessor = glb.json.accessors[index];
  if (!accessor.normalized) return values;
  const scale = { 5120: 127, 5122: 32767 }[accessor.componentType];
  return values.map((c) => Math.max(c / scale, -1));
};
const frameNormals = (glb, primitive, f) => {
  const base = normalised(glb, primitive.attributes.NORMAL);
  if (f === 0) return base;
  const difference = normalised(glb, primitive.targets[f - 1].NORMAL);
  return base.map((v, i) => v + difference[i]);
};
const hasNormals = pc.attributes.NORMAL !== undefined && pc.targets.every((t) => t.NORMAL !== undefined);
check(hasNormals, 'the compact clip carries NORMAL in its base and in every morph target');
if (hasNormals) {
  const baseAccessor = compact.json.accessors[pc.attributes.NORMAL];
  check(baseAccessor.componentType === 5120 && baseAccessor.normalized === true, 'its base normals are normalised int8 (KHR_mesh_quantization)');
  const base = frameNormals(compact, pc, 0);
  let longest = 0;
  for (let i = 0; i < base.length; i += 3) longest = Math.max(longest, Math.abs(Math.hypot(base[i], base[i + 1], base[i + 2]) - 1));
  check(longest <= 0.005, `its base normals are unit within 0.005 (worst ${longest.toExponential(2)})`);
  // The decoder's rule on the float clip's own positions: Σ (b − a) × (c − a) over a vertex's
  // triangles, normalised (codec/decoder/player/decoder.cpp, area_weighted_normals).
  const triangles = read(plain, pf.indices);
  let ruleWorst = 0, worstNormal = 0;
  for (let f = 0; f <= pf.targets.length; ++f) {
    const positions = basePlain.map((v, i) => v + (f ? read(plain, pf.targets[f - 1].POSITION)[i] : 0));
    const sum = new Float64Array(positions.length);
    for (let t = 0; t < triangles.length; t += 3) {
      const [a, b, c] = [triangles[t], triangles[t + 1], triangles[t + 2]].map((v) => 3 * v);
      const u = [0, 1, 2].map((k) => positions[b + k] - positions[a + k]), w = [0, 1, 2].map((k) => positions[c + k] - positions[a + k]);
      const n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
      for (const v of [a, b, c]) for (let k = 0; k < 3; ++k) sum[v + k] += n[k];
    }
    const exact = frameNormals(plain, pf, f), quantised = frameNormals(compact, pc, f);
    for (let v = 0; v < sum.length; v += 3) {
      const length = Math.hypot(sum[v], sum[v + 1], sum[v + 2]);
      if (length === 0) continue;  // a vertex on no triangle: any unit normal
      for (let k = 0; k < 3; ++k) {
        ruleWorst = Math.max(ruleWorst, Math.abs(sum[v + k] / length - exact[v + k]));
        worstNormal = Math.max(worstNormal, Math.abs(quantised[v + k] - exact[v + k]));
      }
    }
  }
  check(ruleWorst <= 1e-4, `the float clip's normals are the decoder's (area-weighted) in all ${pf.targets.length + 1} frames: worst ${ruleWorst.toExponential(2)} a component`);
  check(worstNormal <= 1 / 127 + 1e-6, `the compact clip's normals are the float clip's within 1/127 a component in every frame (worst ${worstNormal.toExponential(3)})`);
}
const ratio = plain.bytes.length / compact.bytes.length;
console.log(`sizes: ${plain.bytes.length} bytes in floats, ${compact.bytes.length} compact: ${ratio.toFixed(2)}x smaller`);
process.exit(failures ? 1 : 0);
