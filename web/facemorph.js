// facemorph.js: play a .fmv file in a web page (spec/web.md). An ES module without dependencies;
// the three.js helper takes the page's own THREE.
//
//   import { FacemorphPlayer, FacemorphThree } from './facemorph.js';
//   const player = await FacemorphPlayer.open('face.fmv');          // a URL (range requests) or bytes
//   player.info();                                                  // fps, range, counts, texture size, units
//   const frame = await player.decode(1.45);                        // typed arrays: positions, normals, uvs, indices
//   const face = new FacemorphThree(THREE, player, { camera });     // a THREE.Mesh kept up to date; camera framed on it
//   scene.add(face.mesh); await face.update(t);                     // per animation frame
//
// web/examples/minimal.html is a whole page that plays a file this way.
//
// Decoding runs in a Web Worker (web/worker.js) with the WebAssembly decoder: the page's thread
// only uploads arrays and images. A URL is read by HTTP range requests: the header, the index and
// each chunk's framing first, then each keyframe group when a frame needs it, so playback starts
// before the file has arrived and a seek fetches only what it needs.

const here = new URL('.', import.meta.url);

export class FacemorphPlayer {
  constructor(worker, opened) {
    this.worker = worker;
    this.opened = opened;
    this.pending = new Map();
    this.nextId = 1;
    worker.onmessage = (event) => this.receive(event.data);
    worker.onerror = (event) => {
      for (const { reject } of this.pending.values()) reject(new Error(event.message || 'the decoding worker failed'));
      this.pending.clear();
    };
  }

  // Opens `source`: a URL (string or URL) or the file's bytes (ArrayBuffer, Uint8Array, Blob/File).
  // options: {base: where web/ is served (default: beside this module), limits: fm_decoder_options
  // fields as {maxGridN, maxKeyframes, maxTextureSize, maxMemoryBytes, maxWork}, name: what errors
  // call the file (default: the URL as given, or the File's name)}.
  // A file the decoder refuses rejects with an Error whose statusName is the C API's (fm_status_name:
  // 'truncated', 'corrupt', ...) and whose message reads as fmdec's does: "error (truncated): NAME:
  // truncated: chunk TGOP at offset 2928 needs 1571 bytes, only 48 left".
  static async open(source, options = {}) {
    const base = new URL(options.base || here, location.href);
    const worker = new Worker(new URL('worker.js', base), { type: 'module' });
    const player = new FacemorphPlayer(worker, null);
    const name = options.name ?? (typeof source === 'string' ? source : source instanceof URL ? source.href : source.name ?? 'the bytes given');
    const message = { type: 'open', name, moduleUrl: new URL('dist/facemorph_wasm.mjs', base).href, wasmUrl: new URL('dist/facemorph_wasm.wasm', base).href, limits: options.limits };
    let transfer = [];
    if (typeof source === 'string' || source instanceof URL) {
      message.url = new URL(source, location.href).href;
    } else {
      // A copy goes to the worker (transferred): the caller's bytes stay the caller's.
      const buffer = source instanceof Blob ? await source.arrayBuffer() : source instanceof ArrayBuffer ? source.slice(0) : source.slice().buffer;
      message.bytes = buffer;
      transfer = [buffer];
    }
    try {
      player.opened = await player.call(message, transfer);
    } catch (error) {
      worker.terminate();
      throw error;
    }
    return player;
  }

  call(message, transfer = []) {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.pending.set(id, { resolve, reject });
      this.worker.postMessage({ ...message, id }, transfer);
    });
  }

  receive(message) {
    const waiting = this.pending.get(message.id);
    if (!waiting) return;
    this.pending.delete(message.id);
    if (message.type === 'error') {
      const error = new Error(message.message);
      error.statusName = message.status;
      waiting.reject(error);
    } else {
      waiting.resolve(message.result);
    }
  }

  // What the file holds (fm_info): fps, firstTime, lastTime, duration, rangeBegin, rangeEnd,
  // keyframeCount, gridN, maxVertexCount, maxTriangleCount, hasHoles, textureSize, units.
  info() {
    return this.opened.info;
  }
  keyframeTimes() {
    return this.opened.keyframeTimes;
  }
  // What opening fetched: bytesFetched, requests, fileBytes, groups, openMs.
  openStats() {
    const { info, keyframeTimes, ...stats } = this.opened;
    return stats;
  }

  // The frame at t (seconds): {time, vertexCount, triangleCount, positions, normals, uvs, indices
  // (Float32Array / Uint32Array, the page's own), weights: [{keyframe, weight}] (the texture blend),
  // textures: [{keyframe, bitmap}] (images not in options.haveTextures), decodeMs, bytesFetched}.
  // options: {clamp, flipV (v down, as WebGL samples an image uploaded without flipping), haveTextures, texture}.
  decode(t, options = {}) {
    const flags = (options.clamp ? 1 : 0) | (options.keepHolesFilled ? 2 : 0) | (options.flipV ? 4 : 0);
    return this.call({ type: 'decode', t, flags, haveTextures: options.haveTextures || [], wantTexture: options.texture !== false });
  }

  close() {
    this.worker.terminate();
    for (const { reject } of this.pending.values()) reject(new Error('closed'));
    this.pending.clear();
  }
}

// The texture as the native decoder makes it: Σ wᵢ · texture of keyframe kᵢ, up to six keyframes
// (every local spline blends at most six), rounded to the byte as fm_decoder_decode rounds
// (floor(sum · 255 + ½) / 255); lit as fmdec --preview lights it (codec/meshkit/render): a headlight,
// 0.25 + 0.75 |n · z| in the camera's frame, n the decoder's vertex normals interpolated across the
// triangle (smooth), or the triangle's own where that interpolation vanishes.
const MAX_BLEND = 6;
const vertexShader = `
varying vec2 vUv;
varying vec3 vViewPosition;
varying vec3 vNormal;
void main() {
  vUv = uv;
  vNormal = normalMatrix * normal;
  vec4 view = modelViewMatrix * vec4(position, 1.0);
  vViewPosition = view.xyz;
  gl_Position = projectionMatrix * view;
}`;
const fragmentShader = `
uniform sampler2D maps[${MAX_BLEND}];
uniform float weights[${MAX_BLEND}];
uniform float textured;
uniform float corrected[${MAX_BLEND}];
uniform mat3 rangeFix;
uniform vec3 rangeOffset;
varying vec2 vUv;
varying vec3 vViewPosition;
varying vec3 vNormal;
void main() {
  vec3 colour = vec3(0.0);
  vec3 texel;
  // corrected: the browser converted that image as limited range (worker.js); undone here.
  ${Array.from({ length: MAX_BLEND }, (_, i) => `texel = texture2D(maps[${i}], vUv).rgb;
  colour += weights[${i}] * mix(texel, rangeFix * texel + rangeOffset, corrected[${i}]);`).join('\n  ')}
  colour = clamp(floor(colour * 255.0 + 0.5) / 255.0, 0.0, 1.0);
  colour = mix(vec3(200.0 / 255.0), colour, textured);
  float normalLength = length(vNormal);
  vec3 n = normalLength > 1e-12 ? vNormal / normalLength : normalize(cross(dFdx(vViewPosition), dFdy(vViewPosition)));
  gl_FragColor = vec4(colour * (0.25 + 0.75 * abs(n.z)), 1.0);
}`;

export class FacemorphThree {
  // THREE: the page's three.js module. Keeps `mesh` (a THREE.Mesh whose BufferGeometry has room for
  // every frame of the file) and its textures up to date with update(t).
  // options: {camera: a THREE.PerspectiveCamera or OrthographicCamera that the first frame decoded
  // frames (fitCamera), so a face in metres or millimetres, wherever the capture put it, is in view;
  // margin: fitCamera's (1.15); maxTextures: textures kept (12)}.
  constructor(THREE, player, options = {}) {
    this.THREE = THREE;
    this.player = player;
    const info = player.info();
    this.info = info;
    const geometry = new THREE.BufferGeometry();
    const attribute = (n, size) => new THREE.BufferAttribute(new Float32Array(n * size), size).setUsage(THREE.DynamicDrawUsage);
    geometry.setAttribute('position', attribute(info.maxVertexCount, 3));
    geometry.setAttribute('normal', attribute(info.maxVertexCount, 3));
    geometry.setAttribute('uv', attribute(info.maxVertexCount, 2));
    geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(3 * info.maxTriangleCount), 1).setUsage(THREE.DynamicDrawUsage));
    geometry.setDrawRange(0, 0);
    this.geometry = geometry;
    this.blank = new THREE.DataTexture(new Uint8Array([204, 204, 204, 255]), 1, 1);
    this.blank.needsUpdate = true;
    this.material = new THREE.ShaderMaterial({
      uniforms: {
        maps: { value: Array(MAX_BLEND).fill(this.blank) },
        weights: { value: Array(MAX_BLEND).fill(0) },
        textured: { value: info.textureSize > 0 ? 1 : 0 },
        corrected: { value: Array(MAX_BLEND).fill(0) },
        rangeFix: { value: new THREE.Matrix3() },
        rangeOffset: { value: new THREE.Vector3() },
      },
      vertexShader, fragmentShader, side: THREE.DoubleSide,
    });
    this.mesh = new THREE.Mesh(geometry, this.material);
    this.textures = new Map();  // keyframe -> THREE.Texture, most recently used last
    this.maxTextures = options.maxTextures || 12;
    this.showTexture = info.textureSize > 0;
    this.indicesFixed = false;
    this.busy = null;
    this.last = null;
    this.camera = options.camera || null;
    this.margin = options.margin ?? 1.15;
  }

  // The sphere around the face as last drawn, in world coordinates (the mesh's own transform
  // applied): a THREE.Sphere, or null before the first frame.
  boundingSphere() {
    if (!this.geometry.boundingSphere) return null;
    this.mesh.updateWorldMatrix(true, false);
    return this.geometry.boundingSphere.clone().applyMatrix4(this.mesh.matrixWorld);
  }

  // Aims `camera` at the face and fits the bounding sphere, times `margin`, inside its view: a
  // perspective camera keeps its direction and moves to the distance where the sphere fits both
  // field-of-view angles; an orthographic one gets a frustum of the sphere's size (its aspect kept).
  // near and far are set around the sphere. Does nothing before the first frame; returns the sphere.
  fitCamera(camera, margin = this.margin) {
    const sphere = this.boundingSphere();
    if (!sphere || !(sphere.radius > 0)) return sphere;
    const THREE = this.THREE;
    const radius = sphere.radius * margin;
    const direction = camera.getWorldDirection(new THREE.Vector3());
    if (camera.isPerspectiveCamera) {
      const vertical = THREE.MathUtils.degToRad(camera.fov) / 2;
      const horizontal = Math.atan(Math.tan(vertical) * camera.aspect);
      const distance = radius / Math.sin(Math.min(vertical, horizontal));
      camera.position.copy(sphere.center).addScaledVector(direction, -distance);
      camera.near = Math.max(distance - 2 * radius, distance / 1000);
      camera.far = distance + 2 * radius;
    } else {
      const aspect = (camera.right - camera.left) / (camera.top - camera.bottom) || 1;
      const half = aspect >= 1 ? radius : radius / aspect;
      camera.left = -half * aspect; camera.right = half * aspect;
      camera.top = half; camera.bottom = -half;
      camera.zoom = 1;
      camera.position.copy(sphere.center).addScaledVector(direction, -2 * radius);
      camera.near = 0;
      camera.far = 4 * radius;
    }
    camera.lookAt(sphere.center);
    camera.updateProjectionMatrix();
    return sphere;
  }

  set wireframe(on) { this.material.wireframe = on; }
  get wireframe() { return this.material.wireframe; }
  set textured(on) {
    this.showTexture = on && this.info.textureSize > 0;
    this.material.uniforms.textured.value = this.showTexture ? 1 : 0;
  }
  get textured() { return this.showTexture; }

  // Decodes t and updates the mesh; a call while one is in flight returns that one (a frame is
  // never queued behind another: playback skips rather than lags). Resolves with the frame's stats.
  update(t, options = {}) {
    if (this.busy) return this.busy;
    this.busy = this.decodeAndApply(t, options).finally(() => { this.busy = null; });
    return this.busy;
  }

  async decodeAndApply(t, options) {
    const frame = await this.player.decode(t, {
      clamp: options.clamp ?? true, flipV: true, texture: this.info.textureSize > 0,
      haveTextures: [...this.textures.keys()],
    });
    this.apply(frame);
    const first = !this.last;
    this.last = frame;
    if (first && this.camera) this.fitCamera(this.camera);
    return frame;
  }

  apply(frame) {
    const THREE = this.THREE;
    const g = this.geometry;
    g.attributes.position.array.set(frame.positions);
    g.attributes.normal.array.set(frame.normals);
    g.attributes.uv.array.set(frame.uvs);
    for (const name of ['position', 'normal', 'uv']) {
      g.attributes[name].clearUpdateRanges?.();
      g.attributes[name].needsUpdate = true;
    }
    // Without holes every frame has the same triangles: uploaded once.
    if (!this.indicesFixed || this.info.hasHoles) {
      g.index.array.set(frame.indices);
      g.index.needsUpdate = true;
      this.indicesFixed = true;
    }
    g.setDrawRange(0, 3 * frame.triangleCount);
    g.computeBoundingSphere();
    for (const { keyframe, bitmap, correction } of frame.textures) {
      const texture = new THREE.Texture(bitmap);
      texture.userData.corrected = correction ? 1 : 0;
      if (correction) {
        this.material.uniforms.rangeFix.value.fromArray(correction.matrix);
        this.material.uniforms.rangeOffset.value.setScalar(correction.offset);
      }
      texture.flipY = false;  // decoded with v down (FM_DECODE_FLIP_V): row 0 is v = 0
      texture.colorSpace = THREE.NoColorSpace;
      texture.minFilter = THREE.LinearFilter;
      texture.generateMipmaps = false;
      texture.needsUpdate = true;
      this.textures.set(keyframe, texture);
    }
    const maps = Array(MAX_BLEND).fill(this.blank), weights = Array(MAX_BLEND).fill(0), corrected = Array(MAX_BLEND).fill(0);
    frame.weights.slice(0, MAX_BLEND).forEach(({ keyframe, weight }, i) => {
      const texture = this.textures.get(keyframe);
      if (!texture) return;
      // Most recently used last, for eviction.
      this.textures.delete(keyframe);
      this.textures.set(keyframe, texture);
      maps[i] = texture;
      weights[i] = weight;
      corrected[i] = texture.userData.corrected;
    });
    this.material.uniforms.maps.value = maps;
    this.material.uniforms.weights.value = weights;
    this.material.uniforms.corrected.value = corrected;
    while (this.textures.size > this.maxTextures) {
      const [oldest, texture] = this.textures.entries().next().value;
      if (frame.weights.some((w) => w.keyframe === oldest)) break;
      texture.dispose();
      texture.image?.close?.();
      this.textures.delete(oldest);
    }
  }

  dispose() {
    this.geometry.dispose();
    this.material.dispose();
    for (const texture of this.textures.values()) texture.dispose();
    this.textures.clear();
  }
}
