//! A corpus of deliberately broken inputs, made by this test. Every case must give `Err`
//! (never a panic, a hang or an absurd allocation) whose message says what is wrong and
//! where; the cases the importer tolerates must give `Ok` with the change reported.
//!
//! Small valid glTF documents are built here (buffers as base64 data URIs or GLB binary
//! chunks) and then broken one way at a time. Real assets (truncation, random byte flips)
//! are read from `$SKINLET_ASSETS` (default `../shared/assets` next to the workspace);
//! those tests print a note and pass when the folder is missing.

mod common;
use common::SplitMix as Rng;
use common::assets_dir;

use base64::Engine as _;
use skinlet::Asset;
use skinlet::import::{load_bytes, load_gltf_slice, load_obj_str};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------
// Largest single allocation, per thread: catches "allocate a huge Vec, then check bounds".

struct Watch;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
}

// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Watch {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static WATCH: Watch = Watch;

/// Largest single allocation (bytes) made by this thread while running `f`.
fn largest_alloc<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.with(|l| l.set(0));
    let r = f();
    (r, LARGEST.with(|l| l.get()))
}

/// No input of this file may make the importer ask for more than this in one allocation.
const ALLOC_LIMIT: usize = 64 << 20;

// ---------------------------------------------------------------------------------------
// Loading helpers.

/// The message the importer gives when it caught a panic inside the glTF parser: a caught
/// panic is still a bug, so the fuzz-style tests below reject it.
const CONTAINED_PANIC: &str = "the glTF parser could not read it";

fn load(name: &str, bytes: &[u8]) -> Result<Asset, String> {
    let (r, largest) = largest_alloc(|| load_bytes(bytes, Path::new(name)));
    assert!(largest <= ALLOC_LIMIT, "{name}: one allocation of {largest} bytes for a {}-byte input", bytes.len());
    r.map_err(|e| e.to_string())
}

/// Asserts `Err` whose message names the file and contains every fragment.
#[track_caller]
fn expect_err(name: &str, bytes: &[u8], fragments: &[&str]) -> String {
    match load(name, bytes) {
        Ok(_) => panic!("{name}: expected an error, the importer accepted it"),
        Err(msg) => {
            println!("{msg}");
            assert!(msg.contains(name), "{name}: error does not name the file: {msg}");
            for f in fragments {
                assert!(msg.contains(f), "{name}: error lacks {f:?}: {msg}");
            }
            assert!(!msg.contains(CONTAINED_PANIC), "{name}: the parser panicked: {msg}");
            msg
        }
    }
}

#[track_caller]
fn expect_ok(name: &str, bytes: &[u8]) -> Asset {
    match load(name, bytes) {
        Ok(a) => a,
        Err(msg) => panic!("{name}: expected Ok, got: {msg}"),
    }
}

#[track_caller]
fn has_warning(asset: &Asset, fragments: &[&str]) {
    assert!(
        asset.report.warnings.iter().any(|w| fragments.iter().all(|f| w.contains(f))),
        "no warning with {fragments:?} in {:?}",
        asset.report.warnings
    );
}

// ---------------------------------------------------------------------------------------
// A tiny glTF writer.

const I8: u32 = 5120;
const U8: u32 = 5121;
const U16: u32 = 5123;
const U32: u32 = 5125;
const F32: u32 = 5126;

fn components(ty: &str) -> usize {
    match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => unreachable!("{ty}"),
    }
}

#[derive(Clone)]
struct View {
    offset: usize,
    length: usize,
    stride: Option<usize>,
}

#[derive(Clone)]
struct Acc {
    view: Option<usize>,
    offset: usize,
    component: u32,
    count: usize,
    ty: &'static str,
    /// More members, each starting with a comma (min/max, sparse, normalized).
    extra: String,
}

#[derive(Clone, Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<View>,
    accs: Vec<Acc>,
    meshes: Vec<String>,
    nodes: Vec<String>,
    skins: Vec<String>,
    animations: Vec<String>,
    /// More top-level members, each a complete `"key": value`.
    top: Vec<String>,
    /// Replaces the buffer's data URI.
    uri: Option<String>,
}

fn le_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_u16(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_u32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

impl Doc {
    /// Appends `data` (4-byte aligned) to the buffer and makes a buffer view of it.
    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(View { offset: self.bin.len(), length: data.len(), stride: None });
        self.bin.extend_from_slice(data);
        self.views.len() - 1
    }

    fn accessor(&mut self, data: &[u8], component: u32, ty: &'static str, count: usize) -> usize {
        let view = self.view(data);
        self.accs.push(Acc { view: Some(view), offset: 0, component, count, ty, extra: String::new() });
        self.accs.len() - 1
    }

    fn f32s(&mut self, v: &[f32], ty: &'static str) -> usize {
        let a = self.accessor(&le_f32(v), F32, ty, v.len() / components(ty));
        if ty == "VEC3" {
            // glTF requires min/max on POSITION accessors; NaN cannot be written in JSON.
            let (mut lo, mut hi) = ([0f32; 3], [0f32; 3]);
            for (i, x) in v.iter().enumerate().filter(|(_, x)| x.is_finite()) {
                lo[i % 3] = lo[i % 3].min(*x);
                hi[i % 3] = hi[i % 3].max(*x);
            }
            self.accs[a].extra = format!(r#","min":{lo:?},"max":{hi:?}"#);
        }
        a
    }

    fn u16s(&mut self, v: &[u16], ty: &'static str) -> usize {
        self.accessor(&le_u16(v), U16, ty, v.len() / components(ty))
    }

    fn json_with(&self, buffer: &str) -> String {
        let mut m = vec![r#""asset":{"version":"2.0"}"#.to_string(), format!(r#""buffers":[{buffer}]"#)];
        let views: Vec<String> = self
            .views
            .iter()
            .map(|v| {
                let stride = v.stride.map(|s| format!(r#","byteStride":{s}"#)).unwrap_or_default();
                format!(r#"{{"buffer":0,"byteOffset":{},"byteLength":{}{stride}}}"#, v.offset, v.length)
            })
            .collect();
        let accs: Vec<String> = self
            .accs
            .iter()
            .map(|a| {
                let view = a.view.map(|v| format!(r#""bufferView":{v},"#)).unwrap_or_default();
                format!(
                    r#"{{{view}"byteOffset":{},"componentType":{},"count":{},"type":"{}"{}}}"#,
                    a.offset, a.component, a.count, a.ty, a.extra
                )
            })
            .collect();
        for (key, list) in [
            ("bufferViews", &views),
            ("accessors", &accs),
            ("meshes", &self.meshes),
            ("nodes", &self.nodes),
            ("skins", &self.skins),
            ("animations", &self.animations),
        ] {
            if !list.is_empty() {
                m.push(format!(r#""{key}":[{}]"#, list.join(",")));
            }
        }
        m.extend(self.top.iter().cloned());
        format!("{{{}}}", m.join(","))
    }

    /// The document as .gltf text with the buffer as a data URI.
    fn gltf(&self) -> Vec<u8> {
        let b64 = base64::engine::general_purpose::STANDARD.encode(&self.bin);
        let uri = self.uri.clone().unwrap_or_else(|| format!("data:application/octet-stream;base64,{b64}"));
        self.json_with(&format!(r#"{{"byteLength":{},"uri":"{uri}"}}"#, self.bin.len())).into_bytes()
    }

    /// The document as .glb with the buffer in the BIN chunk.
    fn glb(&self) -> Vec<u8> {
        glb(self.json_with(&format!(r#"{{"byteLength":{}}}"#, self.bin.len())).as_bytes(), Some(&self.bin))
    }
}

/// A GLB container: header, JSON chunk (space padded), optional BIN chunk (zero padded).
fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let mut j = json.to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut body = Vec::new();
    body.extend_from_slice(&(j.len() as u32).to_le_bytes());
    body.extend_from_slice(b"JSON");
    body.extend_from_slice(&j);
    if let Some(bin) = bin {
        let mut b = bin.to_vec();
        while !b.len().is_multiple_of(4) {
            b.push(0);
        }
        body.extend_from_slice(&(b.len() as u32).to_le_bytes());
        body.extend_from_slice(b"BIN\0");
        body.extend_from_slice(&b);
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + body.len()) as u32).to_le_bytes());
    out.extend_from_slice(&body);
    out
}

/// The base character: a ladder of 6 vertices (4 triangles) skinned to a two-joint chain
/// (node 1 "hip" -> node 2 "knee"), node 0 "body" draws it, one rotation clip on the knee.
#[derive(Clone)]
struct Rig {
    positions: Vec<[f32; 3]>,
    indices: Option<Vec<u16>>,
    mode: Option<u32>,
    joint_component: u32,
    joints: Option<Vec<[u32; 4]>>,
    weights: Option<Vec<[f32; 4]>>,
    ibm: Option<Vec<[f32; 16]>>,
    times: Vec<f32>,
    rotations: Vec<[f32; 4]>,
    interpolation: &'static str,
}

/// Accessor numbers of a built [`Rig`].
struct Ids {
    pos: usize,
    joints: Option<usize>,
    weights: Option<usize>,
    ibm: Option<usize>,
}

const IDENTITY: [f32; 16] = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.];
const KNEE_IBM: [f32; 16] = [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., -1., 0., 1.];

impl Rig {
    /// The valid base document, to be broken one way at a time.
    fn base() -> Self {
        let s = std::f32::consts::FRAC_1_SQRT_2;
        Rig {
            positions: vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.], [0., 2., 0.], [1., 2., 0.]],
            indices: Some(vec![0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4]),
            mode: None,
            joint_component: U16,
            joints: Some(vec![[0, 1, 0, 0]; 6]),
            weights: Some(vec![
                [1., 0., 0., 0.],
                [1., 0., 0., 0.],
                [0.5, 0.5, 0., 0.],
                [0.5, 0.5, 0., 0.],
                [0., 1., 0., 0.],
                [0., 1., 0., 0.],
            ]),
            ibm: Some(vec![IDENTITY, KNEE_IBM]),
            times: vec![0.0, 0.5, 1.0],
            rotations: vec![[0., 0., 0., 1.], [0., 0., 0.382_683_43, 0.923_879_5], [0., 0., s, s]],
            interpolation: "LINEAR",
        }
    }
}

impl Rig {
    fn build(&self) -> (Doc, Ids) {
        let mut d = Doc::default();
        let pos = d.f32s(&self.positions.concat(), "VEC3");
        let idx = self.indices.as_ref().map(|i| d.u16s(i, "SCALAR"));
        let joints = self.joints.as_ref().map(|j| {
            let flat: Vec<u32> = j.concat();
            let bytes = match self.joint_component {
                U8 => flat.iter().map(|&x| x as u8).collect(),
                U16 => le_u16(&flat.iter().map(|&x| x as u16).collect::<Vec<_>>()),
                _ => le_u32(&flat),
            };
            d.accessor(&bytes, self.joint_component, "VEC4", j.len())
        });
        let weights = self.weights.as_ref().map(|w| d.f32s(&w.concat(), "VEC4"));
        let ibm = self.ibm.as_ref().map(|m| d.f32s(&m.concat(), "MAT4"));
        let times = d.f32s(&self.times, "SCALAR");
        let rots = d.f32s(&self.rotations.concat(), "VEC4");

        let mut attrs = vec![format!(r#""POSITION":{pos}"#)];
        attrs.extend(joints.map(|j| format!(r#""JOINTS_0":{j}"#)));
        attrs.extend(weights.map(|w| format!(r#""WEIGHTS_0":{w}"#)));
        let mut prim = format!(r#""attributes":{{{}}}"#, attrs.join(","));
        if let Some(i) = idx {
            prim += &format!(r#","indices":{i}"#);
        }
        if let Some(m) = self.mode {
            prim += &format!(r#","mode":{m}"#);
        }
        d.meshes.push(format!(r#"{{"name":"ladder","primitives":[{{{prim}}}]}}"#));
        d.nodes = vec![
            r#"{"name":"body","mesh":0,"skin":0}"#.into(),
            r#"{"name":"hip","children":[2]}"#.into(),
            r#"{"name":"knee","translation":[0,1,0]}"#.into(),
        ];
        let ibm_member = ibm.map(|i| format!(r#","inverseBindMatrices":{i}"#)).unwrap_or_default();
        d.skins.push(format!(r#"{{"name":"legs","joints":[1,2]{ibm_member}}}"#));
        d.animations.push(format!(
            r#"{{"name":"bend","samplers":[{{"input":{times},"output":{rots},"interpolation":"{}"}}],"channels":[{{"sampler":0,"target":{{"node":2,"path":"rotation"}}}}]}}"#,
            self.interpolation
        ));
        (d, Ids { pos, joints, weights, ibm })
    }

    fn gltf(&self) -> Vec<u8> {
        self.build().0.gltf()
    }
}

fn mesh0(a: &Asset) -> &skinlet::SkinnedMesh {
    &a.meshes[0].primitives[0].geometry
}

// ---------------------------------------------------------------------------------------
// Real assets.

fn asset(rel: &str) -> Option<Vec<u8>> {
    let path = assets_dir()?.join(rel);
    match std::fs::read(&path) {
        Ok(b) => Some(b),
        Err(e) => {
            println!("note: cannot read {}: {e}; skipping", path.display());
            None
        }
    }
}

/// Random bytes.
impl Rng {
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }
}

/// Loads anything: Ok or Err are both fine, but an Err must say something and must not
/// be a caught parser panic.
fn survive(name: &str, bytes: &[u8]) {
    if let Err(msg) = load(name, bytes) {
        assert!(!msg.trim().is_empty(), "{name}: empty error message");
        assert!(!msg.contains(CONTAINED_PANIC), "{name}: the parser panicked on this input: {msg}");
    }
}

fn json_chunk_end(glb: &[u8]) -> usize {
    20 + u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize
}

#[test]
fn real_assets_load() {
    for rel in ["skinned/Fox.glb", "skinned/RiggedSimple.glb", "skinned/SimpleSkin.gltf", "skinned/CesiumMan.glb"] {
        let Some(bytes) = asset(rel) else { return };
        let a = expect_ok(rel, &bytes);
        assert_eq!(a.skins.len(), 1, "{rel}");
        assert!(!a.clips.is_empty(), "{rel}");
    }
}

#[test]
fn truncated_glb() {
    for rel in ["skinned/Fox.glb", "skinned/RiggedSimple.glb"] {
        let Some(full) = asset(rel) else { return };
        let mut cuts: Vec<usize> = (0..=80).collect();
        cuts.extend((81..full.len()).step_by(997));
        let json_end = json_chunk_end(&full);
        cuts.extend([json_end - 1, json_end, json_end + 1, json_end + 8, json_end + 9, full.len() - 4, full.len() - 1]);
        for &cut in &cuts {
            let name = format!("{rel}.cut{cut}.glb");
            // A plain cut: the header's length gives it away.
            expect_err(&name, &full[..cut], &[if cut == 0 { "empty" } else { "truncated" }]);
            // A cut whose header length (and BIN chunk length) were rewritten to match, as a
            // careless tool would: still an error, found later.
            if cut >= 12 {
                let mut patched = full[..cut].to_vec();
                patched[8..12].copy_from_slice(&(cut as u32).to_le_bytes());
                if cut >= json_end + 8 {
                    patched[json_end..json_end + 4].copy_from_slice(&((cut - json_end - 8) as u32).to_le_bytes());
                }
                let pname = format!("{rel}.cut{cut}-patched.glb");
                let msg = expect_err(&pname, &patched, &[]);
                assert!(
                    ["truncated", "exceeds", "EOF", "byteLength", "chunk"].iter().any(|f| msg.contains(f)),
                    "{pname}: unhelpful error: {msg}"
                );
            }
        }
    }
}

#[test]
fn random_bytes() {
    let mut rng = Rng(0x5EED_0001);
    let mut lengths: Vec<usize> = (0..=64).collect();
    lengths.extend([100, 255, 1000, 4096, 65_536, 200_000]);
    for &len in &lengths {
        for trial in 0..8 {
            let mut bytes = rng.bytes(len);
            // Some trials get a plausible start so the parser goes deeper.
            match trial % 4 {
                1 if len >= 12 => {
                    bytes[..8].copy_from_slice(b"glTF\x02\0\0\0");
                    bytes[8..12].copy_from_slice(&(len as u32).to_le_bytes());
                }
                2 if len >= 1 => bytes[0] = b'{',
                3 if len >= 2 => bytes[..2].copy_from_slice(b"v "),
                _ => {}
            }
            for ext in ["glb", "gltf", "obj", "bin"] {
                survive(&format!("random-{len}-{trial}.{ext}"), &bytes);
            }
        }
    }
}

#[test]
fn random_byte_flips_in_real_files() {
    for (rel, seed, trials) in
        [("skinned/RiggedSimple.glb", 1u64, 1500), ("skinned/Fox.glb", 2, 600), ("skinned/SimpleSkin.gltf", 3, 1500)]
    {
        let Some(orig) = asset(rel) else { return };
        let mut rng = Rng(seed);
        // Half of the flips land in the JSON (where structure lives), half anywhere.
        let json_end = if orig.starts_with(b"glTF") { json_chunk_end(&orig) } else { orig.len() };
        let (mut ok, mut err) = (0, 0);
        for trial in 0..trials {
            let mut bytes = orig.clone();
            for _ in 0..1 + rng.below(8) {
                let at = if trial % 2 == 0 { rng.below(json_end) } else { rng.below(bytes.len()) };
                bytes[at] ^= 1 << rng.below(8);
            }
            let name = format!("{rel}.flip{trial}.{}", if json_end == orig.len() { "gltf" } else { "glb" });
            match load(&name, &bytes) {
                Ok(_) => ok += 1,
                Err(msg) => {
                    assert!(!msg.contains(CONTAINED_PANIC), "{name}: the parser panicked: {msg}");
                    err += 1;
                }
            }
        }
        println!("{rel}: {trials} flipped copies: {ok} Ok, {err} Err");
    }
}

#[test]
fn random_line_edits_in_obj() {
    let Some(orig) = asset("static/spot.obj") else { return };
    let text = String::from_utf8(orig).unwrap();
    let lines: Vec<&str> = text.lines().take(3000).collect();
    let mut rng = Rng(7);
    for trial in 0..300 {
        let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        for _ in 0..1 + rng.below(4) {
            let i = rng.below(l.len());
            let mut b = l[i].clone().into_bytes();
            if !b.is_empty() {
                let at = rng.below(b.len());
                b[at] = b"0123456789-./ fvx\te"[rng.below(19)];
            }
            l[i] = String::from_utf8_lossy(&b).into_owned();
        }
        survive(&format!("spot-{trial}.obj"), l.join("\n").as_bytes());
    }
}

// ---------------------------------------------------------------------------------------
// The base documents are valid.

#[test]
fn base_rig_is_valid() {
    let r = Rig::base();
    let (d, _) = r.build();
    for (name, bytes) in [("rig.gltf", d.gltf()), ("rig.glb", d.glb())] {
        let a = expect_ok(name, &bytes);
        let g = mesh0(&a);
        assert_eq!(g.positions.len(), 6);
        assert_eq!(g.triangles, vec![[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]]);
        assert_eq!(a.skins[0].inverse_bind.len(), 2);
        assert_eq!(a.clips[0].rotations[0].values.len(), 3);
        assert!(a.report.warnings.is_empty(), "{:?}", a.report.warnings);
        assert_eq!(a.report.renormalized_vertices, 0);
    }
}

// ---------------------------------------------------------------------------------------
// Containers and buffers.

#[test]
fn glb_container_errors() {
    let (d, _) = Rig::base().build();
    let good = d.glb();

    let mut v1 = good.clone();
    v1[4] = 1;
    expect_err("v1.glb", &v1, &["version 1"]);

    // Header length smaller than the header itself.
    for len in [0u32, 1, 11] {
        let mut b = good.clone();
        b[8..12].copy_from_slice(&len.to_le_bytes());
        expect_err(&format!("hdrlen{len}.glb"), &b, &["length"]);
    }

    let mut b = good.clone();
    b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    expect_err("jsonlen.glb", &b, &["GLB chunk 0 (\"JSON\")", "length 4294967295", "truncated"]);

    let mut b = good.clone();
    b[16..20].copy_from_slice(b"BIN\0");
    expect_err("binfirst.glb", &b, &["GLB chunk 0", "must be the JSON chunk", "BIN"]);

    // A buffer without uri but no BIN chunk.
    let json = d.json_with(&format!(r#"{{"byteLength":{}}}"#, d.bin.len()));
    expect_err("nobin.glb", &glb(json.as_bytes(), None), &["buffer 0", "binary chunk", "has none"]);

    // BIN chunk shorter than the buffer's byteLength.
    let json = d.json_with(&format!(r#"{{"byteLength":{}}}"#, d.bin.len() + 100));
    expect_err("shortbin.glb", &glb(json.as_bytes(), Some(&d.bin)), &["buffer 0", "byteLength", "truncated"]);

    expect_err("empty.glb", b"", &[]);
    expect_err("magic.glb", b"glTF", &["truncated"]);
}

#[test]
fn bad_json() {
    expect_err("junk.gltf", b"{\"asset\": {\"version\": \"2.0\"}, ", &["line 1"]);
    expect_err("noasset.gltf", b"{}", &["asset"]);
    // Deep nesting: an error (not a stack overflow) where the value is kept, skipped where not.
    let (open, close) = ("[".repeat(100_000), "]".repeat(100_000));
    let deep = format!(
        r#"{{"asset":{{"version":"2.0"}},"accessors":[{{"count":1,"componentType":5126,"type":"SCALAR","min":{open}{close}}}]}}"#
    );
    expect_err("deep.gltf", deep.as_bytes(), &["recursion limit exceeded"]);
    let deep = format!(r#"{{"asset":{{"version":"2.0"}},"unknown":{open}{close}}}"#);
    expect_ok("deep_unknown.gltf", deep.as_bytes());
    expect_err("unknown.bin", b"hello", &["unknown file type"]);
    let (d, _) = Rig::base().build();
    let mut d2 = d.clone();
    d2.nodes[0] = r#"{"name":"body","mesh":7,"skin":0}"#.into();
    expect_err("badmesh.gltf", &d2.gltf(), &["nodes[0].mesh", "Index out of bounds"]);
}

#[test]
fn bad_base64() {
    let (mut d, _) = Rig::base().build();
    d.uri = Some("data:application/octet-stream;base64,@@not base64@@".into());
    expect_err("b64.gltf", &d.gltf(), &["buffer 0", "base64"]);
    d.uri = Some("data:application/octet-stream,plain".into());
    expect_err("notb64.gltf", &d.gltf(), &["buffer 0", "not base64"]);
    // Valid base64 but shorter than byteLength.
    d.uri = Some("data:application/octet-stream;base64,AAAA".into());
    expect_err("shortb64.gltf", &d.gltf(), &["buffer 0", "holds 3 bytes", "byteLength"]);
}

fn scratch_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("skinlet-broken-inputs-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn external_buffer() {
    let (mut d, _) = Rig::base().build();
    d.uri = Some("no_such_buffer.bin".into());
    let bytes = d.gltf();
    let dir = scratch_dir("ext");
    let name = dir.join("ext.gltf");
    let err = load_bytes(&bytes, &name).expect_err("missing external buffer must fail").to_string();
    assert!(err.contains("no_such_buffer.bin"), "{err}");
    assert!(err.contains(&dir.display().to_string()), "{err}");
    // Without a folder to resolve it against.
    let err = load_gltf_slice(&bytes, None).expect_err("cannot resolve").to_string();
    assert!(err.contains("buffer 0") && err.contains("no_such_buffer.bin"), "{err}");
    // Percent-encoded name of a file that exists: loads.
    std::fs::write(dir.join("my buffer.bin"), &d.bin).unwrap();
    d.uri = Some("my%20buffer.bin".into());
    let a = load_bytes(&d.gltf(), &name).expect("external buffer present");
    assert_eq!(mesh0(&a).positions.len(), 6);
    // Present but shorter than byteLength.
    std::fs::write(dir.join("my buffer.bin"), &d.bin[..10]).unwrap();
    let err = load_bytes(&d.gltf(), &name).expect_err("short external buffer").to_string();
    assert!(err.contains("buffer 0") && err.contains("holds 10 bytes"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[cfg(unix)]
#[test]
fn external_buffer_that_never_ends() {
    // A device file would be read forever (or until memory runs out).
    let (mut d, _) = Rig::base().build();
    d.uri = Some("/dev/zero".into());
    let err = load_bytes(&d.gltf(), Path::new("dev.gltf")).expect_err("not a file").to_string();
    assert!(err.contains("/dev/zero"), "{err}");
}

// ---------------------------------------------------------------------------------------
// Accessors.

#[test]
fn accessor_out_of_bounds() {
    let (d, ids) = Rig::base().build();
    let p = ids.pos;
    let loc = format!("accessor {p} (mesh 0 (\"ladder\") primitive 0 POSITION)");

    let mut b = d.clone();
    b.accs[p].count = 7;
    expect_err("count.gltf", &b.gltf(), &[&loc, "7 elements of 12 bytes", "do not fit in buffer view 0 (72 bytes)"]);

    let mut b = d.clone();
    b.accs[p].offset = 4;
    expect_err("offset.gltf", &b.gltf(), &[&loc, "at offset 4", "do not fit"]);

    let mut b = d.clone();
    b.accs[p].offset = u64::MAX as usize;
    expect_err("offset_max.gltf", &b.gltf(), &[&loc, "do not fit"]);

    let mut b = d.clone();
    b.accs[p].count = 1 << 50;
    expect_err("count_huge.gltf", &b.gltf(), &[&loc, "do not fit"]);

    let mut b = d.clone();
    b.views[0].length += 1000;
    expect_err("view.gltf", &b.gltf(), &[&loc, "buffer view 0 (offset 0, length 1072) runs past the end of buffer 0"]);

    let mut b = d.clone();
    b.views[0].offset = usize::MAX - 10;
    expect_err("view_offset.gltf", &b.gltf(), &[&loc, "runs past the end of buffer 0"]);

    // A sparse accessor without a buffer view is all zeros but its sparse values, yet not
    // terabytes of zeros.
    let mut b = d.clone();
    let iv = b.view(&le_u16(&[4]));
    let vv = b.view(&le_f32(&[7., 8., 9.]));
    b.accs[p].extra += &format!(
        r#","sparse":{{"count":1,"indices":{{"bufferView":{iv},"componentType":5123}},"values":{{"bufferView":{vv}}}}}"#
    );
    b.accs[p].view = None;
    b.accs[p].count = 1 << 40;
    expect_err("viewless_huge.gltf", &b.gltf(), &[&loc, "unsupported: count 1099511627776 × 3 components"]);
    b.accs[p].count = (1 << 62) + 1;
    expect_err("viewless_overflow.gltf", &b.gltf(), &[&loc, "limit on numbers read from one file"]);
}

#[test]
fn many_references_to_big_data() {
    // A sparse accessor without a buffer view of 833,334 zero positions (20 MB as numbers)
    // in a 1 KB file, used by 100 primitives: 100 copies must not all be made.
    let (mut d, ids) = Rig::base().build();
    let p = ids.pos;
    let iv = d.view(&le_u16(&[4]));
    let vv = d.view(&le_f32(&[7., 8., 9.]));
    d.accs[p].extra += &format!(
        r#","sparse":{{"count":1,"indices":{{"bufferView":{iv},"componentType":5123}},"values":{{"bufferView":{vv}}}}}"#
    );
    d.accs[p].view = None;
    d.accs[p].count = 833_334;
    let prim = format!(r#"{{"attributes":{{"POSITION":{p}}}}}"#);
    d.meshes[0] = format!(r#"{{"name":"ladder","primitives":[{}]}}"#, vec![prim; 100].join(","));
    let bytes = d.gltf();
    assert!(bytes.len() < 10_000, "{}", bytes.len());
    let (r, _) = largest_alloc(|| load_bytes(&bytes, Path::new("refs.gltf")));
    let Err(e) = r else { panic!("refs.gltf: 100 copies of 20 MB were made") };
    let msg = e.to_string();
    assert!(msg.contains("refs.gltf: accessor 0 (mesh 0 (\"ladder\") primitive "), "{msg}");
    assert!(msg.contains("limit on numbers read from one file"), "{msg}");
    // A few references are fine.
    d.meshes[0] = format!(
        r#"{{"name":"ladder","primitives":[{}]}}"#,
        vec![format!(r#"{{"attributes":{{"POSITION":{p}}}}}"#); 3].join(",")
    );
    let a = expect_ok("refs3.gltf", &d.gltf());
    assert_eq!(a.meshes[0].primitives.len(), 3);
    assert_eq!(mesh0(&a).positions.len(), 833_334);
}

#[test]
fn byte_stride_smaller_than_element() {
    let (mut d, ids) = Rig::base().build();
    d.views[0].stride = Some(8);
    expect_err(
        "stride.gltf",
        &d.gltf(),
        &[&format!("accessor {} (", ids.pos), "POSITION", "byteStride 8 is smaller than the element size 12"],
    );
    // A stride that is large enough but walks out of the view.
    d.views[0].stride = Some(16);
    expect_err("stride16.gltf", &d.gltf(), &["POSITION", "with stride 16 do not fit"]);
    // Interleaved data read with a stride works.
    let mut r = Rig::base();
    r.positions = vec![[0., 0., 0.], [9., 9., 9.], [1., 0., 0.], [9., 9., 9.], [0., 1., 0.], [9., 9., 9.]];
    r.indices = Some(vec![0, 1, 2]);
    let (mut d, ids) = r.build();
    d.views[0].stride = Some(24);
    d.accs[ids.pos].count = 3;
    d.accs[ids.joints.unwrap()].count = 3;
    d.accs[ids.weights.unwrap()].count = 3;
    let a = expect_ok("interleaved.gltf", &d.gltf());
    assert_eq!(mesh0(&a).positions, vec![glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y]);
}

#[test]
fn wrong_accessor_types() {
    let (d, ids) = Rig::base().build();
    let mut b = d.clone();
    b.accs[ids.pos].ty = "VEC2";
    b.accs[ids.pos].extra = r#","min":[0,0,0],"max":[1,1,1]"#.into();
    expect_err("vec2.gltf", &b.gltf(), &["POSITION", "expected type [Vec3], found Vec2"]);
    let mut b = d.clone();
    b.accs[1].component = F32;
    b.accs[1].count = 3;
    expect_err("findex.gltf", &b.gltf(), &["accessor 1 (", "indices", "expected unsigned integers, found F32"]);
    let mut b = d.clone();
    b.accs[ids.joints.unwrap()].component = I8;
    expect_err("i8joints.gltf", &b.gltf(), &["JOINTS_0", "expected unsigned integers, found I8"]);
}

#[test]
fn index_out_of_range() {
    let mut r = Rig::base();
    r.indices.as_mut().unwrap()[4] = 9;
    expect_err(
        "index.gltf",
        &r.gltf(),
        &["mesh 0 (\"ladder\") primitive 0", "index 4 is 9, but there are only 6 vertices"],
    );
}

#[test]
fn index_count_not_multiple_of_3() {
    let mut r = Rig::base();
    r.indices.as_mut().unwrap().pop();
    expect_err("indices.gltf", &r.gltf(), &["mesh 0 (\"ladder\") primitive 0", "11 indices is not a multiple of 3"]);
}

#[test]
fn nan_and_inf_in_position() {
    for (tag, bad) in [("nan", f32::NAN), ("inf", f32::INFINITY), ("-inf", f32::NEG_INFINITY)] {
        let mut r = Rig::base();
        r.positions[3][1] = bad;
        expect_err(&format!("{tag}.gltf"), &r.gltf(), &["POSITION", "element 3 holds a NaN or infinite value"]);
    }
}

#[test]
fn sparse_accessors() {
    // Works: vertex 4 replaced.
    let (mut d, ids) = Rig::base().build();
    let iv = d.view(&le_u16(&[4]));
    let vv = d.view(&le_f32(&[7., 8., 9.]));
    let sparse = format!(
        r#","sparse":{{"count":1,"indices":{{"bufferView":{iv},"componentType":5123}},"values":{{"bufferView":{vv}}}}}"#
    );
    d.accs[ids.pos].extra += &sparse;
    let a = expect_ok("sparse.gltf", &d.gltf());
    let g = mesh0(&a);
    assert_eq!(g.positions[4], glam::Vec3::new(7., 8., 9.));
    assert_eq!(g.positions[3], glam::Vec3::new(1., 1., 0.));

    // Works without a buffer view: zeros, then the substitution.
    let mut b = d.clone();
    b.accs[ids.pos].view = None;
    let a = expect_ok("sparse_viewless.gltf", &b.gltf());
    let g = mesh0(&a);
    assert_eq!(g.positions[4], glam::Vec3::new(7., 8., 9.));
    assert_eq!(g.positions[3], glam::Vec3::ZERO);

    // Neither a buffer view nor sparse values: all zeros, as glTF defines it (glTF
    // Transform's `sparse` writes morph targets that move nothing so). The gltf crate's
    // validation wants a buffer view here.
    let mut m = morphed(&[0.5; 18]);
    let t = m.accs.len() - 1;
    m.accs[t].view = None;
    let a = expect_ok("zeros.gltf", &m.gltf());
    assert_eq!(a.meshes[0].primitives[0].targets[0].positions, vec![glam::Vec3::ZERO; 6]);
    // A target that moves nothing leaves the character no morph weights, so a bake with an
    // envelope (one range per weight) reads back.
    let c = a.character().unwrap();
    assert!(c.mesh.morphs.weights.is_empty() && c.mesh.morphs.is_empty());
    let clips: Vec<_> = a.clips.iter().collect();
    let (builder, limits, how) =
        (skinlet::meshlet::Builder::SkinAware, Default::default(), skinlet::bounds::refine::Refinement::NONE);
    let mut baked = skinlet::bake::bake(&a, &c, &clips, builder, limits, &how, &mut |_| {}).unwrap().0;
    let envelope =
        skinlet::bounds::envelope::Envelope::from_clips(&a.skeleton, &baked.palette(), &baked.mesh, &clips, 0.1)
            .unwrap();
    skinlet::bake::add_envelope(&mut baked, &a, envelope).unwrap();
    assert_eq!(skinlet::bake::from_bytes(&skinlet::bake::to_bytes(&baked)).unwrap(), baked);

    // Index not below the count.
    let mut b = d.clone();
    let bad = b.view(&le_u16(&[6]));
    b.accs[ids.pos].extra =
        b.accs[ids.pos].extra.replace(&format!(r#""bufferView":{iv},"#), &format!(r#""bufferView":{bad},"#));
    expect_err("sparse_index.gltf", &b.gltf(), &["POSITION", "sparse index 6 (entry 0) is not below the count 6"]);

    // More sparse entries than the index/value views hold.
    let mut b = d.clone();
    b.accs[ids.pos].extra = b.accs[ids.pos].extra.replace(r#""count":1"#, r#""count":1000"#);
    expect_err("sparse_count.gltf", &b.gltf(), &["POSITION", "sparse indices", "do not fit"]);

    // NaN arriving through the substitution.
    let mut b = d.clone();
    b.bin[b.views[vv].offset..b.views[vv].offset + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    expect_err("sparse_nan.gltf", &b.gltf(), &["POSITION", "element 4 holds a NaN"]);
}

// ---------------------------------------------------------------------------------------
// Skin data.

#[test]
fn nan_weights() {
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[2][1] = f32::NAN;
    expect_err("nanw.gltf", &r.gltf(), &["WEIGHTS_0", "element 2 holds a NaN or infinite value"]);
}

#[test]
fn negative_weights() {
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[5] = [1.5, -0.5, 0., 0.];
    expect_err(
        "negw.gltf",
        &r.gltf(),
        &["mesh 0 (\"ladder\") primitive 0", "vertex 5: WEIGHTS_0 component 1 is negative (-0.5)"],
    );
}

#[test]
fn joint_index_out_of_skin() {
    let mut r = Rig::base();
    r.joints.as_mut().unwrap()[3] = [0, 5, 0, 0];
    expect_err(
        "joint.gltf",
        &r.gltf(),
        &["mesh 0 primitive 0 vertex 3", "joint index 5 is out of range", "skin 0", "has 2 joints"],
    );
    // u32 joints (not allowed by the spec, read anyway) above u16.
    let mut r = Rig::base();
    r.joint_component = U32;
    r.joints.as_mut().unwrap()[1] = [70_000, 1, 0, 0];
    expect_err("joint32.gltf", &r.gltf(), &["vertex 1", "joint index 70000 is too large"]);
    // Same, on a vertex whose weights are all zero: it binds to its first joint slot.
    r.weights.as_mut().unwrap()[1] = [0.; 4];
    expect_err("joint32_zero.gltf", &r.gltf(), &["vertex 1", "70000"]);
}

#[test]
fn joints_without_weights() {
    let mut r = Rig::base();
    r.weights = None;
    expect_err(
        "jnw.gltf",
        &r.gltf(),
        &["mesh 0 (\"ladder\") primitive 0", "JOINTS_0 and WEIGHTS_0 must come together"],
    );
    let mut r = Rig::base();
    r.joints = None;
    expect_err("wnj.gltf", &r.gltf(), &["JOINTS_0 and WEIGHTS_0 must come together"]);
    // Count mismatch with POSITION.
    let (mut d, ids) = Rig::base().build();
    d.accs[ids.weights.unwrap()].count = 5;
    expect_err("wcount.gltf", &d.gltf(), &["JOINTS_0/WEIGHTS_0 have 6/5 elements but POSITION has 6"]);
}

#[test]
fn missing_inverse_bind_matrices_is_identity() {
    let mut r = Rig::base();
    r.ibm = None;
    let a = expect_ok("noibm.gltf", &r.gltf());
    has_warning(&a, &["skin 0", "no inverseBindMatrices", "identity"]);
    assert_eq!(a.skins[0].inverse_bind, vec![glam::Mat4::IDENTITY; 2]);
}

#[test]
fn fewer_inverse_bind_matrices_than_joints() {
    let mut r = Rig::base();
    r.ibm = Some(vec![IDENTITY]);
    expect_err("ibm.gltf", &r.gltf(), &["skin 0 (\"legs\")", "1 inverse bind matrices for 2 joints"]);
}

#[test]
fn non_affine_inverse_bind_matrix() {
    let mut r = Rig::base();
    r.ibm.as_mut().unwrap()[1][3] = 0.5;
    expect_err("affine.gltf", &r.gltf(), &["skin 0 (\"legs\")", "inverse bind matrix 1 is not affine"]);
    let mut r = Rig::base();
    r.ibm.as_mut().unwrap()[0][12] = f32::INFINITY;
    let ibm = r.build().1.ibm.unwrap();
    let loc = format!("accessor {ibm} (skin 0 (\"legs\") inverseBindMatrices)");
    expect_err("ibm_inf.gltf", &r.gltf(), &[&loc, "element 0 holds a NaN or infinite value"]);
}

#[test]
fn weights_not_summing_to_one_are_renormalized() {
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[2] = [0.5, 0.25, 0., 0.];
    let a = expect_ok("sum.gltf", &r.gltf());
    assert_eq!(a.report.renormalized_vertices, 1);
    let inf = mesh0(&a).influences.as_ref().unwrap();
    let got: Vec<(u16, f32)> = inf.of(2).collect();
    assert_eq!(got.len(), 2);
    assert_eq!(got[0].0, 0);
    assert!((got[0].1 - 2. / 3.).abs() < 1e-6 && (got[1].1 - 1. / 3.).abs() < 1e-6, "{got:?}");
    // Within 1e-3 of 1: normalized silently, not counted.
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[2] = [0.5, 0.5004, 0., 0.];
    assert_eq!(expect_ok("sum_close.gltf", &r.gltf()).report.renormalized_vertices, 0);
}

#[test]
fn huge_weights_do_not_overflow() {
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[0] = [f32::MAX, f32::MAX, 0., 0.];
    r.joints.as_mut().unwrap()[1] = [1, 1, 1, 0];
    r.weights.as_mut().unwrap()[1] = [f32::MAX, f32::MAX, f32::MAX, 0.];
    let a = expect_ok("bigw.gltf", &r.gltf());
    let inf = mesh0(&a).influences.as_ref().unwrap();
    let v0: Vec<(u16, f32)> = inf.of(0).collect();
    assert_eq!(v0, vec![(0, 0.5), (1, 0.5)]);
    let v1: Vec<(u16, f32)> = inf.of(1).collect();
    assert_eq!(v1, vec![(1, 1.0)]);
    assert_eq!(a.report.renormalized_vertices, 2);
}

#[test]
fn all_zero_weights_are_counted() {
    let mut r = Rig::base();
    r.weights.as_mut().unwrap()[4] = [0.; 4];
    r.joints.as_mut().unwrap()[4] = [1, 0, 0, 0];
    let a = expect_ok("zero.gltf", &r.gltf());
    assert_eq!(a.report.zero_weight_vertices, 1);
    let inf = mesh0(&a).influences.as_ref().unwrap();
    assert_eq!(inf.of(4).collect::<Vec<_>>(), vec![(1, 1.0)]);
}

// ---------------------------------------------------------------------------------------
// Node hierarchy.

#[test]
fn node_cycle() {
    let (mut d, _) = Rig::base().build();
    d.nodes[2] = r#"{"name":"knee","translation":[0,1,0],"children":[1]}"#.into();
    expect_err("cycle.gltf", &d.gltf(), &["node 1 (\"hip\")", "cycle"]);
    // A node that is its own child.
    let (mut d, _) = Rig::base().build();
    d.nodes[2] = r#"{"name":"knee","children":[2]}"#.into();
    expect_err("selfcycle.gltf", &d.gltf(), &["node 2 (\"knee\")", "cycle"]);
}

#[test]
fn node_with_two_parents() {
    let (mut d, _) = Rig::base().build();
    d.nodes[0] = r#"{"name":"body","mesh":0,"skin":0,"children":[2]}"#.into();
    expect_err("parents.gltf", &d.gltf(), &["node 2 (\"knee\")", "has two parents, nodes 0 and 1"]);
    // The same child listed twice by one parent.
    let (mut d, _) = Rig::base().build();
    d.nodes[1] = r#"{"name":"hip","children":[2,2]}"#.into();
    expect_err("twice.gltf", &d.gltf(), &["node 2 (\"knee\")", "twice", "node 1"]);
}

#[test]
fn bad_node_transforms() {
    let (d, _) = Rig::base().build();
    let mut b = d.clone();
    b.nodes[2] = r#"{"name":"knee","rotation":[0,0,0,0]}"#.into();
    expect_err("rot0.gltf", &b.gltf(), &["node 2 (\"knee\")", "rotation quaternion has zero length"]);
    let mut b = d.clone();
    b.nodes[2] = r#"{"name":"knee","translation":[0,1e39,0]}"#.into();
    expect_err("trs_inf.gltf", &b.gltf(), &["node 2 (\"knee\")", "NaN or infinite"]);
    let mut b = d.clone();
    b.nodes[1] = r#"{"name":"hip","children":[2],"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,1, 0,0,0,1]}"#.into();
    expect_err("matrix.gltf", &b.gltf(), &["node 1 (\"hip\")", "matrix is not affine"]);
    // A matrix on an animated node: the spec forbids it; decomposed with a warning.
    let mut b = d.clone();
    b.nodes[2] = r#"{"name":"knee","matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,1,0,1]}"#.into();
    let a = expect_ok("animmatrix.gltf", &b.gltf());
    has_warning(&a, &["node 2 (\"knee\")", "animated but given by a matrix"]);
    assert_eq!(a.skeleton.nodes[2].rest.translation, glam::Vec3::Y);
}

// ---------------------------------------------------------------------------------------
// Animation.

#[test]
fn decreasing_key_times() {
    let mut r = Rig::base();
    r.times = vec![0.0, 1.0, 0.5];
    expect_err(
        "times.gltf",
        &r.gltf(),
        &["animation 0 (\"bend\") channel 0", "key times decrease at key 2: 0.5 after 1"],
    );
    let mut r = Rig::base();
    r.times[1] = f32::NAN;
    expect_err("times_nan.gltf", &r.gltf(), &["animation 0 (\"bend\") channel 0 input", "element 1 holds a NaN"]);
}

#[test]
fn cubic_spline_output_count() {
    let mut r = Rig::base();
    r.interpolation = "CUBICSPLINE";
    expect_err(
        "cubic.gltf",
        &r.gltf(),
        &["animation 0 (\"bend\") channel 0", "3 keys need 9 output values (CUBICSPLINE), found 3"],
    );
    // 3 values per key (in-tangent, value, out-tangent) is right; tangents may be zero.
    let zero = [0f32; 4];
    r.rotations = r.rotations.iter().flat_map(|q| [zero, *q, zero]).collect();
    let a = expect_ok("cubic_ok.gltf", &r.gltf());
    assert_eq!(a.clips[0].rotations[0].values.len(), 9);
    // LINEAR with too many outputs.
    let mut r = Rig::base();
    r.rotations.push([0., 0., 0., 1.]);
    expect_err("linear.gltf", &r.gltf(), &["3 keys need 3 output values (LINEAR), found 4"]);
}

#[test]
fn bad_channel_targets() {
    // The gltf crate does not validate channel targets and unwraps them: these panicked.
    // The path was found by the byte-flip test ("rotation" -> "rotction"). The node was found
    // by the fuzz target run against the unfixed importer (RiggedSimple.glb with
    // "target":{"node":8} among 5 nodes).
    let (d, _) = Rig::base().build();
    let mut b = d.clone();
    b.animations[0] = b.animations[0].replace(r#""path":"rotation""#, r#""path":"rotction""#);
    expect_err(
        "path.gltf",
        &b.gltf(),
        &["animation 0 channel 0", "target path is not translation, rotation, scale or weights"],
    );
    let mut b = d.clone();
    b.animations[0] = b.animations[0].replace(r#""node":2"#, r#""node":9"#);
    expect_err(
        "target.gltf",
        &b.gltf(),
        &["animation 0 channel 0", "target node 9 does not exist (there are 3 nodes)"],
    );
    let mut b = d.clone();
    b.animations[0] = b.animations[0].replace(r#""sampler":0"#, r#""sampler":3"#);
    expect_err("sampler.gltf", &b.gltf(), &["animations[0].channels[0].sampler", "Index out of bounds"]);
    // The gltf validator indexed accessors with POSITION unchecked (a caught panic before).
    let mut b = d.clone();
    b.meshes[0] = b.meshes[0].replace(r#""POSITION":0"#, r#""POSITION":99"#);
    expect_err("posidx.gltf", &b.gltf(), &["mesh 0 primitive 0", "POSITION accessor 99 does not exist"]);
}

#[test]
fn zero_length_rotation_key() {
    let mut r = Rig::base();
    r.rotations[1] = [0.; 4];
    expect_err(
        "qzero.gltf",
        &r.gltf(),
        &["animation 0 (\"bend\") channel 0 output key 1", "rotation quaternion has zero length"],
    );
    // Non-unit keys are normalized.
    let mut r = Rig::base();
    r.rotations[2] = [0., 0., 0., 2.];
    let a = expect_ok("qscale.gltf", &r.gltf());
    assert_eq!(a.clips[0].rotations[0].values[2], glam::Quat::IDENTITY);
}

// ---------------------------------------------------------------------------------------
// Primitive modes, morph targets, extensions.

#[test]
fn points_and_lines_are_skipped() {
    for (mode, what) in [(0, "Points"), (1, "Lines"), (2, "LineLoop"), (3, "LineStrip")] {
        let mut r = Rig::base();
        r.mode = Some(mode);
        let a = expect_ok(&format!("mode{mode}.gltf"), &r.gltf());
        assert!(a.meshes[0].primitives.is_empty());
        has_warning(&a, &["mesh 0 (\"ladder\") primitive 0", what, "skipped"]);
    }
}

#[test]
fn triangle_strips_and_fans() {
    // glTF 2.0 section 3.7.2.1, for vertices v (here: the index list):
    //   strip triangle i = (v[i], v[i + 1 + i % 2], v[i + 2 - i % 2])
    //   fan triangle i   = (v[i + 1], v[i + 2], v[0])
    let mut r = Rig::base();
    r.mode = Some(5);
    r.indices = Some(vec![1, 0, 3, 2, 5, 4]);
    let a = expect_ok("strip.gltf", &r.gltf());
    assert_eq!(mesh0(&a).triangles, vec![[1, 0, 3], [0, 2, 3], [3, 2, 5], [2, 4, 5]]);

    r.indices = None;
    let a = expect_ok("strip_noidx.gltf", &r.gltf());
    assert_eq!(mesh0(&a).triangles, vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]]);

    r.mode = Some(6);
    r.indices = Some(vec![0, 1, 3, 5, 4, 2]);
    let a = expect_ok("fan.gltf", &r.gltf());
    assert_eq!(mesh0(&a).triangles, vec![[1, 3, 0], [3, 5, 0], [5, 4, 0], [4, 2, 0]]);

    // Too short to make a triangle: nothing, no error.
    r.indices = Some(vec![0, 1]);
    let a = expect_ok("fan_short.gltf", &r.gltf());
    assert!(mesh0(&a).triangles.is_empty());

    // The strip's indices are range-checked too.
    r.mode = Some(5);
    r.indices = Some(vec![0, 1, 2, 6]);
    expect_err("strip_idx.gltf", &r.gltf(), &["index 3 is 6, but there are only 6 vertices"]);
}

/// The base rig with one morph target (`delta` per vertex) on its primitive.
fn morphed(delta: &[f32]) -> Doc {
    let (mut d, _) = Rig::base().build();
    let t = d.f32s(delta, "VEC3");
    d.meshes[0] =
        d.meshes[0].replacen(r#""attributes":"#, &format!(r#""targets":[{{"POSITION":{t}}}],"attributes":"#), 1);
    d
}

#[test]
fn morph_targets_load_with_their_weights() {
    let mut d = morphed(&[0.5; 18]);
    d.meshes[0] = d.meshes[0].replacen(r#""name":"ladder","#, r#""name":"ladder","weights":[0.25],"#, 1);
    let a = expect_ok("morph.gltf", &d.gltf());
    let p = &a.meshes[0].primitives[0];
    assert_eq!(p.targets.len(), 1);
    assert_eq!(p.targets[0].positions, vec![glam::Vec3::splat(0.5); 6]);
    assert_eq!(a.meshes[0].weights, [0.25]);
    // Posed at the rest pose, the default weight moves every vertex by a quarter delta.
    let c = a.character().unwrap();
    let (posed, _) = c.posed(&a.skeleton, None, 0.0).unwrap();
    let unmorphed = skinlet::SkinnedMesh { morphs: Default::default(), ..c.mesh.clone() };
    let base = skinlet::skinning::posed_positions(&a.skeleton, &c.palette, &unmorphed, None, None).unwrap();
    for (p, q) in posed.iter().zip(&base) {
        assert!((*p - *q - glam::Vec3::splat(0.125)).length() < 1e-5, "{p} vs {q}");
    }
}

#[test]
fn broken_morph_targets() {
    // A delta accessor of the wrong length, and a NaN delta.
    expect_err(
        "mlen.gltf",
        &morphed(&[0.; 15]).gltf(),
        &["primitive 0", "morph target 0 POSITION has 5 elements but POSITION has 6"],
    );
    let mut nan = vec![0.0; 18];
    nan[7] = f32::NAN;
    expect_err("mnan.gltf", &morphed(&nan).gltf(), &["morph target 0 POSITION", "element 2 holds a NaN"]);
    // Default weights of the wrong count, on the mesh and on the node.
    let mut d = morphed(&[0.; 18]);
    d.meshes[0] = d.meshes[0].replacen(r#""name":"ladder","#, r#""name":"ladder","weights":[0.5,0.5],"#, 1);
    expect_err("mw.gltf", &d.gltf(), &["mesh 0 (\"ladder\")", "2 default weights for 1 morph targets"]);
    let mut d = morphed(&[0.; 18]);
    d.nodes[0] = r#"{"name":"body","mesh":0,"skin":0,"weights":[1,2,3]}"#.into();
    expect_err("nw.gltf", &d.gltf(), &["node 0 (\"body\")", "3 weights for 1 morph targets"]);
    // Primitives of one mesh with different target counts.
    let mut d = morphed(&[0.; 18]);
    let second = d.meshes[0].split(r#""primitives":["#).nth(1).unwrap().trim_end_matches("]}").to_string();
    let without = second.replacen(r#""targets":[{"POSITION":"#, r#""x":[{"POSITION":"#, 1);
    d.meshes[0] = d.meshes[0].replacen("]}", &format!(",{without}]}}"), 1);
    expect_err("mcount.gltf", &d.gltf(), &["primitive 1", "has 0 morph targets, but primitive 0 of the mesh has 1"]);
    // A weights channel whose output count is not keys x targets, and one on a node
    // without morph targets.
    let mut d = morphed(&[0.; 18]);
    let times = d.f32s(&[0.0, 1.0], "SCALAR");
    let w = d.f32s(&[0.0, 1.0, 0.5], "SCALAR");
    let anim = |node: u32| {
        format!(
            r#"{{"name":"blink","samplers":[{{"input":{times},"output":{w}}}],"channels":[{{"sampler":0,"target":{{"node":{node},"path":"weights"}}}}]}}"#
        )
    };
    d.animations.push(anim(0));
    expect_err(
        "wcount.gltf",
        &d.gltf(),
        &["channel 0", "2 keys × 1 morph targets need 2 weight values (LINEAR), found 3"],
    );
    d.animations.pop();
    d.animations.push(anim(1));
    expect_err("wnode.gltf", &d.gltf(), &["channel 0", "node 1, which draws no mesh with morph targets"]);
}

#[test]
fn required_extensions() {
    let (mut d, _) = Rig::base().build();
    // Unknown ones could change the geometry (instances, animated pointers): refused by name.
    for ext in ["EXT_mesh_gpu_instancing", "KHR_animation_pointer", "VENDOR_displacement"] {
        d.top = vec![
            format!(r#""extensionsUsed":["KHR_texture_basisu","{ext}"]"#),
            format!(r#""extensionsRequired":["KHR_texture_basisu","{ext}"]"#),
        ];
        expect_err("ext.gltf", &d.gltf(), &["extensionsRequired", ext]);
    }
    // Textures, image formats, materials, lights: they change no geometry, required or not.
    for ext in [
        "KHR_texture_basisu",
        "EXT_texture_webp",
        "EXT_texture_avif",
        "MSFT_texture_dds",
        "KHR_materials_variants",
        "KHR_materials_clearcoat",
        "KHR_lights_punctual",
        "EXT_lights_image_based",
    ] {
        d.top = vec![format!(r#""extensionsUsed":["{ext}"]"#), format!(r#""extensionsRequired":["{ext}"]"#)];
        expect_ok(&format!("{ext}.gltf"), &d.gltf());
    }
    d.top = vec![
        r#""extensionsUsed":["KHR_draco_mesh_compression"]"#.into(),
        r#""extensionsRequired":["KHR_draco_mesh_compression"]"#.into(),
    ];
    // Draco is decoded: a primitive whose Draco stream is not one is an error naming it.
    let draco =
        r#""extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":0}}},"attributes":"#;
    let mut bad = d.clone();
    bad.meshes[0] = bad.meshes[0].replacen(r#""attributes":"#, draco, 1);
    expect_err("draco.gltf", &bad.gltf(), &["mesh 0 primitive 0 (KHR_draco_mesh_compression)", "does not decode"]);
    // meshopt compression is decoded (here no view uses it).
    d.top = vec![
        r#""extensionsUsed":["EXT_meshopt_compression"]"#.into(),
        r#""extensionsRequired":["EXT_meshopt_compression"]"#.into(),
    ];
    expect_ok("meshopt.gltf", &d.gltf());
    // Extensions that change nothing skinlet reads are accepted even when required.
    d.top = vec![
        r#""extensionsUsed":["KHR_mesh_quantization"]"#.into(),
        r#""extensionsRequired":["KHR_mesh_quantization"]"#.into(),
    ];
    expect_ok("quant.gltf", &d.gltf());
}

/// `extras` may hold any JSON value (glTF only recommends objects): on the root, nodes, meshes, primitives, accessors, skins and animations.
#[test]
fn extras_of_any_type() {
    let (d, _) = Rig::base().build();
    let kinds = [r#"{"id":1,"tags":["a"]}"#, r#"["extra",2]"#, r#""a string""#, "1.5", "true", "null"];
    for (k, extra) in kinds.iter().enumerate() {
        let mut b = d.clone();
        b.top = vec![format!(r#""extras":{extra}"#)];
        b.nodes.iter_mut().for_each(|n| *n = n.replacen('{', &format!(r#"{{"extras":{extra},"#), 1));
        b.meshes[0] = b.meshes[0].replacen(r#""attributes":"#, &format!(r#""extras":{extra},"attributes":"#), 1);
        b.meshes[0] = b.meshes[0].replacen('{', &format!(r#"{{"extras":{extra},"#), 1);
        b.skins.iter_mut().for_each(|s| *s = s.replacen('{', &format!(r#"{{"extras":{extra},"#), 1));
        b.animations.iter_mut().for_each(|a| *a = a.replacen('{', &format!(r#"{{"extras":{extra},"#), 1));
        b.accs.iter_mut().for_each(|a| a.extra += &format!(r#","extras":{extra}"#));
        let a = expect_ok(&format!("extras{k}.gltf"), &b.gltf());
        assert_eq!(mesh0(&a).triangles.len(), 4);
    }
}

/// What only says how a surface looks or where it is seen from never stops an import, even
/// where the glTF crate's validation refuses it: textures whose image is only in an extension
/// (`KHR_texture_basisu`, `EXT_texture_webp`, `EXT_texture_avif` write no `source`), missing
/// or unreadable images, dangling texture, material, sampler and camera indices. Errors in
/// the geometry are still errors, beside them too.
#[test]
fn appearance_never_stops_an_import() {
    let (mut d, _) = Rig::base().build();
    d.meshes[0] = d.meshes[0].replacen(r#""attributes":"#, r#""material":0,"attributes":"#, 1);
    let body = d.nodes[0].clone();
    // What gltfpack -tc writes: the KTX2 image only in the texture's extension.
    d.top = vec![
        r#""extensionsUsed":["KHR_texture_basisu"]"#.into(),
        r#""extensionsRequired":["KHR_texture_basisu"]"#.into(),
        r#""textures":[{"extensions":{"KHR_texture_basisu":{"source":0}}}]"#.into(),
        r#""images":[{"uri":"body.ktx2","mimeType":"image/ktx2"}]"#.into(),
        r#""materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}]"#.into(),
    ];
    expect_ok("basisu.gltf", &d.gltf());
    let look = |textures: &str, images: &str, materials: &str| {
        vec![
            r#""extensionsUsed":["KHR_texture_basisu","EXT_texture_webp","EXT_texture_avif","KHR_lights_punctual"]"#
                .to_string(),
            r#""extensionsRequired":["KHR_texture_basisu","EXT_texture_webp","EXT_texture_avif"]"#.to_string(),
            format!(r#""textures":[{textures}]"#),
            format!(r#""images":[{images}]"#),
            format!(r#""materials":[{materials}]"#),
            r#""samplers":[{"magFilter":1234,"wrapS":7}]"#.to_string(),
            r#""cameras":[{"type":"fisheye"}]"#.to_string(),
        ]
    };
    let material = r#"{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}},"normalTexture":{"index":2}}"#;
    let extension_only = [
        r#"{"sampler":0,"extensions":{"KHR_texture_basisu":{"source":0}}}"#,
        r#"{"extensions":{"EXT_texture_webp":{"source":1}}}"#,
        r#"{"extensions":{"EXT_texture_avif":{"source":2}}}"#,
    ]
    .join(",");
    let images = [
        r#"{"uri":"no-such-file.ktx2","mimeType":"image/ktx2"}"#,
        r#"{"uri":"data:image/webp;base64,bm90IGFuIGltYWdl","mimeType":"image/webp"}"#,
        r#"{"bufferView":0,"mimeType":"image/avif"}"#,
    ]
    .join(",");
    d.top = look(&extension_only, &images, material);
    // A camera on the drawing node, a missing one on another.
    d.nodes[0] = body.replacen('{', r#"{"camera":0,"#, 1);
    let a = expect_ok("appearance.gltf", &d.gltf());
    assert_eq!(mesh0(&a).triangles.len(), 4);
    expect_ok("appearance.glb", &d.glb());
    // Dangling indices: a texture's image, a material's texture, a primitive's material, a
    // node's camera; an image with neither a URI nor a buffer view.
    let mut b = d.clone();
    b.top = look(r#"{"source":9,"sampler":4}"#, "{}", r#"{"emissiveTexture":{"index":5}}"#);
    b.meshes[0] = b.meshes[0].replacen(r#""material":0"#, r#""material":3"#, 1);
    b.nodes[0] = body.replacen('{', r#"{"camera":6,"#, 1);
    expect_ok("dangling.gltf", &b.gltf());
    // Geometry errors beside them are still reported.
    let mut c = d.clone();
    c.accs[0].view = Some(99);
    expect_err("geometry.gltf", &c.gltf(), &["invalid glTF", "accessors[0].bufferView: Index out of bounds"]);
}

// ---------------------------------------------------------------------------------------
// OBJ.

#[test]
fn broken_obj() {
    let head = "# test\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: &[(&str, &str, &[&str])] = &[
        ("badnum.obj", "v 0 0 0\nv 1 x 0\n", &["line 2", "bad coordinate \"x\""]),
        ("short_v.obj", "v 0 0 0\nv 1 0\n", &["line 2", "vertex needs 3 coordinates"]),
        ("nan_v.obj", "v 0 0 0\nv nan 0 0\n", &["line 2", "NaN or infinite"]),
        ("inf_v.obj", "v 1e39 0 0\n", &["line 1", "NaN or infinite"]),
        (
            "range.obj",
            &format!("{head}f 1 2 9\n"),
            &["line 5", "face index 9 is out of range (only 3 vertices so far)"],
        ),
        ("zero.obj", &format!("{head}f 0 1 2\n"), &["line 5", "face index 0 is out of range"]),
        ("neg.obj", &format!("{head}f -1 -2 -4\n"), &["line 5", "face index -4 is out of range"]),
        ("huge.obj", &format!("{head}f 1 2 99999999999999999999\n"), &["line 5", "bad face index"]),
        ("two.obj", &format!("{head}f 1 2\n"), &["line 5", "face has 2 vertices (needs 3 or more)"]),
        ("badidx.obj", &format!("{head}f 1 2 three\n"), &["line 5", "bad face index \"three\""]),
        ("empty.obj", "", &["no faces"]),
        ("blank.obj", "\n\n  \n", &["no faces"]),
        ("nofaces.obj", head, &["no faces"]),
    ];
    for (name, text, fragments) in cases {
        expect_err(name, text.as_bytes(), fragments);
        // The same through load_obj_str directly.
        let e = load_obj_str(text, name).expect_err(name).to_string();
        assert!(fragments.iter().all(|f| e.contains(f)), "{name}: {e}");
    }
    expect_err("latin1.obj", b"v 0 0 0 \xff\n", &["not UTF-8"]);
    // Tolerated forms: slashes, negative indices, quads (fan-triangulated).
    let a = expect_ok("ok.obj", format!("{head}v 1 1 0\nf 1/1/1 2//2 -1\nf 1 2 4 3\n").as_bytes());
    assert_eq!(mesh0(&a).triangles, vec![[0, 1, 3], [0, 1, 3], [0, 3, 2]]);
}

#[test]
fn skinned_node_whose_primitive_has_no_weights() {
    // The file imports (it can be inspected), but its character cannot be built: glTF
    // requires JOINTS_0/WEIGHTS_0 on every primitive of a node with a skin.
    let mut r = Rig::base();
    (r.joints, r.weights) = (None, None);
    let a = expect_ok("noweights.gltf", &r.gltf());
    let e = a.character().unwrap_err().to_string();
    for f in ["node 0", "mesh 0 (\"ladder\") primitive 0", "skin 0", "no JOINTS_0/WEIGHTS_0"] {
        assert!(e.contains(f), "lacks {f:?}: {e}");
    }
}
