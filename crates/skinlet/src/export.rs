//! Writes an [`Asset`] as a glTF 2.0 binary (.glb): nodes (TRS or matrix), every mesh's
//! triangle primitives (positions, normals, indices, JOINTS_0/WEIGHTS_0 and JOINTS_1/
//! WEIGHTS_1 for eight influences), skins with their inverse bind matrices, and clips with
//! their channels in the stored interpolation (CUBICSPLINE tangents kept), morph targets
//! (POSITION and NORMAL deltas, mesh and node default weights, one `weights` channel per
//! node holding all its targets), and the scenes (or, for an asset without, one scene of
//! every root node). What skinlet reads back is the same asset (tested), so the demo
//! character can be handed to other glTF tools (`skinlet demo --glb`).

use crate::clip::Channel;
use crate::model::Asset;
use crate::{Error, Result};
use serde_json::{Value, json};

const FLOAT: u32 = 5126;
const U16: u32 = 5123;
const U32: u32 = 5125;

#[derive(Default)]
struct Writer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Writer {
    /// Appends one accessor of `count` elements of `ty` with components of `component`.
    fn accessor(&mut self, bytes: &[u8], component: u32, count: usize, ty: &str, extra: Value) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        let mut a = json!({"bufferView": self.views.len() - 1, "componentType": component, "count": count, "type": ty});
        if let (Some(a), Value::Object(e)) = (a.as_object_mut(), extra) {
            a.extend(e);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats(&mut self, v: &[f32], n: usize, ty: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let extra = if ty == "VEC3" && !v.is_empty() {
            // POSITION needs min and max; harmless elsewhere.
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for c in v.chunks_exact(3) {
                (0..3).for_each(|k| (lo[k], hi[k]) = (lo[k].min(c[k]), hi[k].max(c[k])));
            }
            json!({"min": lo, "max": hi})
        } else if ty == "SCALAR" && !v.is_empty() {
            json!({"min": [v.iter().copied().fold(f32::MAX, f32::min)], "max": [v.iter().copied().fold(f32::MIN, f32::max)]})
        } else {
            json!({})
        };
        self.accessor(&bytes, FLOAT, v.len() / n, ty, extra)
    }

    fn channel<T: Copy>(&mut self, c: &Channel<T>, flat: impl Fn(T) -> Vec<f32>, n: usize, ty: &str) -> Value {
        let input = self.floats(&c.times, 1, "SCALAR");
        let values: Vec<f32> = c.values.iter().flat_map(|&v| flat(v)).collect();
        let output = self.floats(&values, n, ty);
        json!({"input": input, "output": output, "interpolation": c.interpolation.name()})
    }
}

/// One glTF `weights` sampler per node that `clip` animates morph weights of: per key every
/// target's value (CUBICSPLINE: in-tangents, values, out-tangents), a target without a
/// channel holding its default weight. The node's channels must share key times and
/// interpolation, as one glTF sampler does.
fn weight_samplers(asset: &Asset, clip: &crate::clip::Clip, w: &mut Writer) -> Result<Vec<(u32, Value)>> {
    let mut by_node: std::collections::BTreeMap<u32, Vec<&crate::clip::WeightChannel>> = Default::default();
    for c in &clip.weights {
        by_node.entry(c.channel.node).or_default().push(c);
    }
    let mut out = Vec::new();
    for (node, channels) in by_node {
        let mesh = (asset.instances.iter().find(|i| i.node == node))
            .and_then(|i| asset.meshes.get(i.mesh as usize))
            .ok_or_else(|| Error::invalid(format!("clip {:?}", clip.name), format!("node {node} draws no mesh")))?;
        let first = &channels[0].channel;
        if channels.iter().any(|c| c.channel.times != first.times || c.channel.interpolation != first.interpolation) {
            return Err(Error::unsupported(
                format!("clip {:?} node {node}", clip.name),
                "morph weight channels with different keys cannot be written as one glTF weights channel",
            ));
        }
        let targets = mesh.morph_targets();
        let defaults = asset.node_weights.get(&node).unwrap_or(&mesh.weights);
        let per_key = if first.interpolation == crate::clip::Interpolation::CubicSpline { 3 } else { 1 };
        let mut values = Vec::with_capacity(per_key * first.times.len() * targets);
        for i in 0..per_key * first.times.len() {
            for target in 0..targets as u32 {
                let value = match channels.iter().find(|c| c.target == target) {
                    Some(c) => c.channel.values[i],
                    None if per_key == 1 || i % 3 == 1 => defaults.get(target as usize).copied().unwrap_or(0.0),
                    None => 0.0,
                };
                values.push(value);
            }
        }
        let input = w.floats(&first.times, 1, "SCALAR");
        let output = w.floats(&values, 1, "SCALAR");
        out.push((node, json!({"input": input, "output": output, "interpolation": first.interpolation.name()})));
    }
    Ok(out)
}

/// The .glb bytes of `asset`.
pub fn to_glb(asset: &Asset) -> Result<Vec<u8>> {
    let mut w = Writer::default();
    let sk = &asset.skeleton;
    let mut nodes: Vec<Value> = (sk.nodes.iter())
        .map(|n| match n.matrix {
            Some(m) => json!({"name": n.name, "matrix": m.to_cols_array()}),
            None => json!({"name": n.name, "translation": n.rest.translation.to_array(),
                "rotation": n.rest.rotation.to_array(), "scale": n.rest.scale.to_array()}),
        })
        .collect();
    for (i, n) in sk.nodes.iter().enumerate() {
        if let Some(p) = n.parent {
            let children = nodes[p as usize].as_object_mut().expect("an object").entry("children").or_insert(json!([]));
            children.as_array_mut().expect("an array").push(json!(i));
        }
    }
    for inst in &asset.instances {
        let node =
            nodes.get_mut(inst.node as usize).ok_or_else(|| Error::invalid("export", "instance of a missing node"))?;
        node["mesh"] = json!(inst.mesh);
        if let Some(s) = inst.skin {
            node["skin"] = json!(s);
        }
        if let Some(weights) = asset.node_weights.get(&inst.node) {
            node["weights"] = json!(weights);
        }
    }
    let mut meshes = Vec::new();
    for m in &asset.meshes {
        let mut prims = Vec::new();
        for p in &m.primitives {
            let g = &p.geometry;
            let flat = |v: &[glam::Vec3]| v.iter().flat_map(|x| x.to_array()).collect::<Vec<f32>>();
            let mut attributes = json!({"POSITION": w.floats(&flat(&g.positions), 3, "VEC3")});
            if !g.normals.is_empty() {
                attributes["NORMAL"] = json!(w.floats(&flat(&g.normals), 3, "VEC3"));
            }
            if let Some(inf) = &g.influences {
                for set in 0..inf.stride / 4 {
                    let slots = |v: usize| v * inf.stride + 4 * set..v * inf.stride + 4 * set + 4;
                    let joints: Vec<u8> = (0..inf.vertex_count())
                        .flat_map(|v| inf.joints[slots(v)].iter().flat_map(|j| j.to_le_bytes()).collect::<Vec<_>>())
                        .collect();
                    let weights: Vec<f32> =
                        (0..inf.vertex_count()).flat_map(|v| inf.weights[slots(v)].to_vec()).collect();
                    attributes[format!("JOINTS_{set}")] =
                        json!(w.accessor(&joints, U16, inf.vertex_count(), "VEC4", json!({})));
                    attributes[format!("WEIGHTS_{set}")] = json!(w.floats(&weights, 4, "VEC4"));
                }
            }
            let indices: Vec<u8> = g.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
            let indices = w.accessor(&indices, U32, 3 * g.triangles.len(), "SCALAR", json!({}));
            let mut prim = json!({"attributes": attributes, "indices": indices, "mode": 4});
            if !p.targets.is_empty() {
                let targets: Vec<Value> = (p.targets.iter())
                    .map(|t| {
                        let mut target = json!({"POSITION": w.floats(&flat(&t.positions), 3, "VEC3")});
                        if !t.normals.is_empty() {
                            target["NORMAL"] = json!(w.floats(&flat(&t.normals), 3, "VEC3"));
                        }
                        target
                    })
                    .collect();
                prim["targets"] = json!(targets);
            }
            prims.push(prim);
        }
        let mut mesh = json!({"name": m.name, "primitives": prims});
        if !m.weights.is_empty() {
            mesh["weights"] = json!(m.weights);
        }
        meshes.push(mesh);
    }
    let mut skins = Vec::new();
    for s in &asset.skins {
        let ibm: Vec<f32> = s.inverse_bind.iter().flat_map(|m| m.to_cols_array()).collect();
        let ibm = w.floats(&ibm, 16, "MAT4");
        skins.push(json!({"name": s.name, "joints": s.joints, "inverseBindMatrices": ibm}));
    }
    let mut animations = Vec::new();
    for clip in &asset.clips {
        let (mut samplers, mut channels) = (Vec::new(), Vec::new());
        let mut add = |sampler: Value, node: u32, path: &str| {
            samplers.push(sampler);
            channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}));
        };
        for c in &clip.translations {
            add(w.channel(c, |v| v.to_array().to_vec(), 3, "VEC3"), c.node, "translation");
        }
        for c in &clip.rotations {
            add(w.channel(c, |v| v.to_array().to_vec(), 4, "VEC4"), c.node, "rotation");
        }
        for c in &clip.scales {
            add(w.channel(c, |v| v.to_array().to_vec(), 3, "VEC3"), c.node, "scale");
        }
        for (node, sampler) in weight_samplers(asset, clip, &mut w)? {
            add(sampler, node, "weights");
        }
        animations.push(json!({"name": clip.name, "samplers": samplers, "channels": channels}));
    }
    // The asset's scenes, or one holding every root node (how skinlet reads a file without).
    let scenes: Vec<Value> = if asset.scenes.is_empty() {
        let roots: Vec<usize> = (0..sk.nodes.len()).filter(|&i| sk.nodes[i].parent.is_none()).collect();
        vec![json!({"nodes": roots})]
    } else {
        asset.scenes.iter().map(|s| json!({"nodes": s})).collect()
    };
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "skinlet"},
        "scene": asset.default_scene.unwrap_or(0), "scenes": scenes, "nodes": nodes, "meshes": meshes,
        "buffers": [{"byteLength": w.bin.len()}], "bufferViews": w.views, "accessors": w.accessors,
    });
    if !skins.is_empty() {
        doc["skins"] = json!(skins);
    }
    if !animations.is_empty() {
        doc["animations"] = json!(animations);
    }
    let mut text = serde_json::to_vec(&doc).map_err(|e| Error::invalid("export", e.to_string()))?;
    text.resize(text.len().next_multiple_of(4), b' ');
    w.bin.resize(w.bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + text.len() + 8 + w.bin.len();
    let total = u32::try_from(total).map_err(|_| Error::unsupported("export", "a .glb over 4 GiB"))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(w.bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&w.bin);
    Ok(out)
}
