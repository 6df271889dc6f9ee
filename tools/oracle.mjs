// three.js as an independent glTF runtime for skinlet's pose tests.
//
//   node tools/oracle.mjs FILE.glb CLIP T1 [T2 ...]
//
// Loads FILE.glb with three's GLTFLoader (images, textures and materials removed first:
// node has no image decoder, and they do not move vertices), plays animation CLIP (an index)
// with an AnimationMixer at each time, and prints one JSON object: for each time, every mesh
// primitive three built, with the glTF node, mesh and primitive it came from and its vertex
// positions in scene space. three samples the animation, builds the node hierarchy and reads
// the accessors; the positions follow glTF's definition from three's matrices: a skinned
// primitive is sum(w * boneWorld * boneInverse * p) (glTF ignores the drawing node's
// transform), a rigid one nodeWorld * p, p with three's morph targets applied. Weights are
// divided by their sum, as glTF allows and skinlet does (three's shaders use them as stored),
// and rotation keys are normalized, as glTF requires them to be (some files are off by 1e-4;
// three would turn a quaternion of length 0.9997 into a matrix that also scales).
// Each part also carries `triangles`, the triangles three draws for it (its index count, or
// vertex count without indices, over 3).
//
// Compressed files: meshopt views are decoded by three's MeshoptDecoder; Draco primitives by
// the Draco decoder three ships (examples/jsm/libs/draco, Google's decoder compiled to
// JavaScript), run in this process: three's DRACOLoader needs Web Workers, which node lacks,
// so `dracoInProcess` below stands in for it with the same interface.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';

const [file, clipArg, ...timeArgs] = process.argv.slice(2);
const times = timeArgs.map(Number);

function withoutImages(glb) {
  const jsonLength = glb.readUInt32LE(12);
  const json = JSON.parse(glb.subarray(20, 20 + jsonLength).toString('utf8'));
  for (const key of ['images', 'textures', 'samplers', 'materials']) delete json[key];
  for (const mesh of json.meshes ?? []) for (const p of mesh.primitives) delete p.material;
  let text = Buffer.from(JSON.stringify(json), 'utf8');
  text = Buffer.concat([text, Buffer.alloc((4 - (text.length % 4)) % 4, 0x20)]);
  const rest = glb.subarray(20 + jsonLength);
  const head = Buffer.alloc(20);
  head.write('glTF', 0);
  head.writeUInt32LE(2, 4);
  head.writeUInt32LE(20 + text.length + rest.length, 8);
  head.writeUInt32LE(text.length, 12);
  head.write('JSON', 16);
  const out = Buffer.concat([head, text, rest]);
  return out.buffer.slice(out.byteOffset, out.byteOffset + out.length);
}

// The Draco decoder module, loaded on first use (an Emscripten script written for browsers
// and CommonJS: evaluated with the `require` and `__dirname` it expects).
let draco = null;
async function dracoModule() {
  if (!draco) {
    const path = fileURLToPath(import.meta.resolve('three/examples/jsm/libs/draco/draco_decoder.js'));
    const source = readFileSync(path, 'utf8');
    const factory = new Function('require', '__dirname', `${source}\nreturn DracoDecoderModule;`);
    draco = await factory(createRequire(path), path.slice(0, path.lastIndexOf('/')))();
  }
  return draco;
}

// Decodes one Draco stream into a BufferGeometry: `attributeIds` maps three's attribute name to
// the stream's attribute id, `attributeTypes` to the typed array the glTF accessor declares.
async function decodeDraco(bytes, attributeIds, attributeTypes) {
  const d = await dracoModule();
  const decoder = new d.Decoder();
  const mesh = new d.Mesh();
  try {
    const status = decoder.DecodeArrayToMesh(new Int8Array(bytes), bytes.byteLength, mesh);
    if (!status.ok() || mesh.ptr === 0) throw new Error(`Draco: ${status.error_msg()}`);
    const geometry = new THREE.BufferGeometry();
    const faces = mesh.num_faces();
    const index = new Uint32Array(3 * faces);
    const face = new d.DracoInt32Array();
    for (let f = 0; f < faces; f++) {
      decoder.GetFaceFromMesh(mesh, f, face);
      for (let k = 0; k < 3; k++) index[3 * f + k] = face.GetValue(k);
    }
    d.destroy(face);
    geometry.setIndex(new THREE.BufferAttribute(index, 1));
    const readers = {
      Float32Array: ['DracoFloat32Array', 'GetAttributeFloatForAllPoints'],
      Int8Array: ['DracoInt8Array', 'GetAttributeInt8ForAllPoints'],
      Uint8Array: ['DracoUInt8Array', 'GetAttributeUInt8ForAllPoints'],
      Int16Array: ['DracoInt16Array', 'GetAttributeInt16ForAllPoints'],
      Uint16Array: ['DracoUInt16Array', 'GetAttributeUInt16ForAllPoints'],
      Uint32Array: ['DracoUInt32Array', 'GetAttributeUInt32ForAllPoints'],
    };
    for (const [name, id] of Object.entries(attributeIds)) {
      const type = attributeTypes[name] ?? 'Float32Array';
      const [arrayClass, getter] = readers[type];
      const attribute = decoder.GetAttributeByUniqueId(mesh, id);
      const values = new d[arrayClass]();
      decoder[getter](mesh, attribute, values);
      const out = new globalThis[type](values.size());
      for (let i = 0; i < out.length; i++) out[i] = values.GetValue(i);
      d.destroy(values);
      geometry.setAttribute(name, new THREE.BufferAttribute(out, attribute.num_components()));
    }
    return geometry;
  } finally {
    d.destroy(mesh);
    d.destroy(decoder);
  }
}

// What GLTFLoader asks of a DRACOLoader.
const dracoInProcess = {
  preload() { return this; },
  decodeDracoFile(bytes, onLoad, attributeIds, attributeTypes, _colorSpace, onError) {
    return decodeDraco(bytes, attributeIds, attributeTypes).then(onLoad, onError);
  },
};

const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder).setDRACOLoader(dracoInProcess);
const gltf = await new Promise((resolve, reject) => loader.parse(withoutImages(readFileSync(file)), '', resolve, reject));
const assoc = gltf.parser.associations;
const scene = gltf.scene;
const mixer = new THREE.AnimationMixer(scene);
const clip = gltf.animations[Number(clipArg)];
if (clip) {
  for (const track of clip.tracks) {
    if (!(track instanceof THREE.QuaternionKeyframeTrack)) continue;
    // CUBICSPLINE stores in-tangent, value, out-tangent per key: normalize the values only.
    const cubic = track.values.length === 12 * track.times.length;
    const v = track.values;
    for (let k = 0; k < v.length / 4; k++) {
      if (cubic && k % 3 !== 1) continue;
      const n = Math.hypot(v[4 * k], v[4 * k + 1], v[4 * k + 2], v[4 * k + 3]);
      for (let c = 0; c < 4; c++) v[4 * k + c] /= n;
    }
  }
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.play();
}

function nodeOf(object) {
  for (let o = object; o; o = o.parent) {
    const a = assoc.get(o);
    if (a && a.nodes !== undefined) return a.nodes;
  }
  return null;
}

const out = [];
for (const t of times) {
  mixer.setTime(t);
  scene.updateMatrixWorld(true);
  const parts = [];
  scene.traverse((o) => {
    if (!o.isMesh) return;
    const a = assoc.get(o) ?? {};
    const geometry = o.geometry;
    const n = geometry.attributes.position.count;
    const positions = new Array(3 * n);
    const p = new THREE.Vector3();
    const q = new THREE.Vector3();
    const sum = new THREE.Vector3();
    const m = new THREE.Matrix4();
    const morphed = THREE.Mesh.prototype.getVertexPosition;
    for (let i = 0; i < n; i++) {
      morphed.call(o, i, p);
      if (o.isSkinnedMesh) {
        const index = geometry.attributes.skinIndex;
        const weight = geometry.attributes.skinWeight;
        sum.set(0, 0, 0);
        let total = 0;
        for (let k = 0; k < 4; k++) total += weight.getComponent(i, k);
        for (let k = 0; k < 4; k++) {
          const w = weight.getComponent(i, k) / total;
          if (w === 0) continue;
          const j = index.getComponent(i, k);
          m.multiplyMatrices(o.skeleton.bones[j].matrixWorld, o.skeleton.boneInverses[j]);
          sum.addScaledVector(q.copy(p).applyMatrix4(m), w);
        }
        p.copy(sum);
      } else {
        p.applyMatrix4(o.matrixWorld);
      }
      positions[3 * i] = p.x;
      positions[3 * i + 1] = p.y;
      positions[3 * i + 2] = p.z;
    }
    const triangles = (geometry.index ? geometry.index.count : n) / 3;
    parts.push({ node: nodeOf(o), mesh: a.meshes ?? null, primitive: a.primitives ?? null, triangles, positions });
  });
  out.push({ time: t, parts });
}
process.stdout.write(JSON.stringify({ clip: clip ? clip.name : null, samples: out }));
