//! Run-time culling costs, one core.
//!
//! - `meshlets/*`: per-meshlet culling (both tests, per-joint setup included) of every
//!   instance of a crowd for one frame; criterion's elements are meshlets.
//! - `joint-aabb/*`: whole-mesh box updates from per-joint boxes for 100 and 1,000 instances
//!   (the PR's many_foxes scene); elements are joint boxes. `bevy-baseline` reimplements the
//!   Bevy pull request's update as it describes it: joint boxes `{center, half_size}` in mesh
//!   space (shared by all instances, as in the mesh asset), each joint's world transform
//!   fetched through its entity (location lookup with generation check, then the table row,
//!   as an ECS query does), multiplied by its inverse bind pose, Arvo's method into world
//!   space, then the world box moved into entity space by the inverse entity transform.
//!   `bevy-baseline-flat` is the same math with entity index = row (an idealized layout).
//!   `skinlet` is [`JointBoxes::update`] on joint-space boxes with the skin's contiguous
//!   entity-space joint matrices; `skinlet-folded` the same after folding leaf joints twice
//!   (elements still count the unfolded joint boxes: the work of bounding the same skin).
//!
//! Run: `cargo bench -p skinlet --bench culling`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Affine3A, Vec3A};
use skinlet::Asset;
use skinlet::bake::bake;
use skinlet::bounds::refine::Refinement;
use skinlet::clip::Clip;
use skinlet::cull::crowd::{CrowdParams, crowd};
use skinlet::cull::joint_aabb::{JointBoxes, JointSpace};
use skinlet::cull::meshlet::{JointFrame, MeshletCuller, Tests};
use skinlet::meshlet::{Builder, MeshletLimits};
use skinlet::pose::Poser;
use std::hint::black_box;
use std::path::PathBuf;

fn assets() -> Vec<(String, Asset)> {
    let dir = std::env::var_os("SKINLET_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/assets")));
    ["Xbot.glb", "Fox.glb"]
        .iter()
        .filter_map(|f| skinlet::import::load(&dir.join("skinned").join(f)).ok().map(|a| (f.to_string(), a)))
        .collect()
}

/// Joint matrices of `n` instances at random times: (entity-space joint globals, world-space
/// joint globals, model matrices).
fn poses(asset: &Asset, skin: u32, n: usize) -> (Vec<Vec<Affine3A>>, Vec<Vec<Affine3A>>, Vec<Affine3A>) {
    let skin = &asset.skins[skin as usize];
    let mesh = asset.combined_mesh(asset.instances.iter().find_map(|i| i.skin));
    let scene = crowd(&mesh.positions, asset.clips.len(), &CrowdParams { instances: n, ..CrowdParams::default() });
    let mut poser = Poser::default();
    let (mut local, mut world, mut models) = (Vec::new(), Vec::new(), Vec::new());
    for p in &scene.placements {
        let clip = asset.clips.get(p.clip);
        let t = clip.map_or(0.0, |c| c.start + p.offset * c.duration());
        let g = poser.globals(&asset.skeleton, clip, t);
        local.push(skin.joints.iter().map(|&j| Affine3A::from_mat4(g[j as usize].as_mat4())).collect());
        world.push(skin.joints.iter().map(|&j| Affine3A::from_mat4((p.model * g[j as usize]).as_mat4())).collect());
        models.push(Affine3A::from_mat4(p.model.as_mat4()));
    }
    (local, world, models)
}

fn meshlet_culling(c: &mut Criterion, name: &str, asset: &Asset, instances: usize) {
    let skin_index = asset.instances.iter().find_map(|i| i.skin).unwrap();
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let (baked, _) =
        bake(asset, skin_index, &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &Refinement::NONE, &mut |_| {})
            .unwrap();
    let skin = &asset.skins[skin_index as usize];
    let culler = MeshletCuller::new(&baked.bounds, &baked.classes, skin.joints.len());
    let (_, world, _) = poses(asset, skin_index, instances);
    let scene = crowd(&baked.mesh.positions, clips.len(), &CrowdParams { instances, ..CrowdParams::default() });
    let mut group = c.benchmark_group("meshlets");
    group.throughput(Throughput::Elements((culler.len() * instances) as u64));
    group.sample_size(20);
    let (mut frame, mut flags, mut visible) = (JointFrame::default(), Vec::new(), Vec::with_capacity(culler.len()));
    group.bench_function(format!("{name}-{instances}-instances/1-core"), |b| {
        b.iter(|| {
            let mut n = 0;
            for joints in &world {
                visible.clear();
                culler.prepare(joints, &scene.camera, Tests::Both, &mut frame);
                n += culler.cull(&frame, &mut flags, &mut visible).visible;
            }
            black_box(n)
        })
    });
    group.finish();
}

/// Bevy's mesh-space joint box.
#[derive(Clone, Copy)]
struct JointAabb {
    center: Vec3A,
    half_size: Vec3A,
}

/// Bevy's data: the mesh asset's joint boxes (with the skin joint of each), the shared
/// inverse bind poses asset, per instance the joint entities and the mesh entity, and one
/// scene-wide array of global transforms (an ECS component table).
struct BevyScene {
    boxes: Vec<(usize, JointAabb)>,
    inverse_bindposes: Vec<Affine3A>,
    instances: Vec<BevyInstance>,
    transforms: Vec<Affine3A>,
    /// Entity index → location; `flat` skips it (entity index = table row).
    metas: Vec<EntityMeta>,
}

impl BevyScene {
    /// `Query::get(entity)` for the global transform: the entity's location, its generation
    /// checked, then the table row (or, `flat`, the row directly: an idealized layout).
    #[inline]
    fn transform(&self, (index, generation): (u32, u32), flat: bool) -> Option<&Affine3A> {
        if flat {
            return self.transforms.get(index as usize);
        }
        let meta = self.metas.get(index as usize)?;
        if meta.generation != generation {
            return None;
        }
        self.transforms.get(meta.row as usize)
    }
}

struct BevyInstance {
    /// Joint entities: (entity index, generation).
    joints: Vec<(u32, u32)>,
    entity: (u32, u32),
}

/// An ECS entity's location: generation and table row (Bevy's `EntityMeta`, reduced).
#[derive(Clone, Copy)]
struct EntityMeta {
    generation: u32,
    row: u32,
}

fn bevy_update(scene: &BevyScene, flat: bool, out: &mut Vec<(Vec3A, Vec3A)>) {
    out.clear();
    for inst in &scene.instances {
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        for &(j, b) in &scene.boxes {
            let Some(joint) = scene.transform(inst.joints[j], flat) else { continue };
            let world_from_mesh = *joint * scene.inverse_bindposes[j];
            let center = world_from_mesh.transform_point3a(b.center);
            let m = world_from_mesh.matrix3;
            let half = m.x_axis.abs() * b.half_size.x + m.y_axis.abs() * b.half_size.y + m.z_axis.abs() * b.half_size.z;
            lo = lo.min(center - half);
            hi = hi.max(center + half);
        }
        // World box to entity space (Arvo again, with the inverse entity transform).
        let Some(entity) = scene.transform(inst.entity, flat) else { continue };
        let inv = entity.inverse();
        let (c, h) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        let m = inv.matrix3;
        let center = inv.transform_point3a(c);
        let half = m.x_axis.abs() * h.x + m.y_axis.abs() * h.y + m.z_axis.abs() * h.z;
        out.push((center - half, center + half));
    }
}

fn joint_aabbs(c: &mut Criterion, name: &str, asset: &Asset, instances: usize) {
    let skin_index = asset.instances.iter().find_map(|i| i.skin).unwrap();
    let skin = &asset.skins[skin_index as usize];
    let mesh = asset.combined_mesh(Some(skin_index));
    let (local, world, models) = poses(asset, skin_index, instances);
    let ours = JointBoxes::new(&mesh, skin, JointSpace::Joint).unwrap();
    let mesh_boxes = JointBoxes::new(&mesh, skin, JointSpace::Mesh).unwrap();
    // Bevy's layout: every instance's entity and joint entities in one transform array.
    let mut bevy = BevyScene {
        boxes: mesh_boxes
            .joints
            .iter()
            .zip(mesh_boxes.center.iter().zip(&mesh_boxes.half))
            .map(|(&j, (&c, &h))| (j as usize, JointAabb { center: c, half_size: h }))
            .collect(),
        inverse_bindposes: skin.inverse_bind.iter().map(|m| Affine3A::from_mat4(*m)).collect(),
        instances: Vec::new(),
        transforms: Vec::new(),
        metas: Vec::new(),
    };
    for (i, joints) in world.iter().enumerate() {
        let entity = bevy.transforms.len() as u32;
        bevy.transforms.push(models[i]);
        let base = bevy.transforms.len() as u32;
        bevy.transforms.extend(joints.iter().copied());
        let ids = (base..base + joints.len() as u32).map(|e| (e, 0)).collect();
        bevy.instances.push(BevyInstance { joints: ids, entity: (entity, 0) });
    }
    // The ECS layout: mesh entities and joint entities live in different archetype tables
    // (here: mesh entities first, then every joint, each in spawn order), and a query
    // reaches a row through the entity's location.
    let n = bevy.transforms.len();
    let is_mesh: Vec<bool> = {
        let mut v = vec![false; n];
        bevy.instances.iter().for_each(|i| v[i.entity.0 as usize] = true);
        v
    };
    let meshes = is_mesh.iter().filter(|&&m| m).count() as u32;
    let (mut next_mesh, mut next_joint) = (0u32, meshes);
    let rows: Vec<u32> = is_mesh
        .iter()
        .map(|&m| {
            let slot = if m { &mut next_mesh } else { &mut next_joint };
            *slot += 1;
            *slot - 1
        })
        .collect();
    let mut ecs = BevyScene {
        boxes: bevy.boxes.clone(),
        inverse_bindposes: bevy.inverse_bindposes.clone(),
        instances: Vec::new(),
        transforms: vec![Affine3A::IDENTITY; n],
        metas: rows.iter().map(|&row| EntityMeta { generation: 0, row }).collect(),
    };
    for (e, &row) in rows.iter().enumerate() {
        ecs.transforms[row as usize] = bevy.transforms[e];
    }
    ecs.instances =
        bevy.instances.iter().map(|i| BevyInstance { joints: i.joints.clone(), entity: i.entity }).collect();
    let mut group = c.benchmark_group("joint-aabb");
    group.sample_size(30);
    group.throughput(Throughput::Elements((mesh_boxes.joints.len() * instances) as u64));
    let mut out = Vec::with_capacity(instances);
    group.bench_function(format!("{name}-{instances}/bevy-baseline"), |b| {
        b.iter(|| {
            bevy_update(&ecs, false, &mut out);
            black_box(&out);
        })
    });
    group.bench_function(format!("{name}-{instances}/bevy-baseline-flat"), |b| {
        b.iter(|| {
            bevy_update(&bevy, true, &mut out);
            black_box(&out);
        })
    });
    group.throughput(Throughput::Elements((ours.joints.len() * instances) as u64));
    let mut boxes = vec![skinlet::cull::joint_aabb::Box3::EMPTY; instances];
    // Every instance's joint matrices in one array, as an engine's matrix palette (and the
    // baseline's transform table) keeps them.
    let local: Vec<Affine3A> = local.concat();
    let joints = skin.joints.len();
    group.bench_function(format!("{name}-{instances}/skinlet"), |b| {
        b.iter(|| {
            ours.update_all(&local, joints, &mut boxes).unwrap();
            black_box(&boxes);
        })
    });
    // Leaf joints folded twice into their ancestors (conservative for the asset's clips).
    let clips: Vec<&Clip> = asset.clips.iter().collect();
    let folded = ours.fold_leaves(&asset.skeleton, skin, &mesh, &clips, 2).unwrap();
    group.throughput(Throughput::Elements((ours.joints.len() * instances) as u64));
    group.bench_function(format!("{name}-{instances}/skinlet-folded"), |b| {
        b.iter(|| {
            folded.update_all(&local, joints, &mut boxes).unwrap();
            black_box(&boxes);
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    for (name, asset) in assets() {
        // 100 characters: the poses stay in cache; 1,000 (the PR's many_foxes): they stream
        // from memory.
        joint_aabbs(c, &name, &asset, 100);
        joint_aabbs(c, &name, &asset, 1000);
        meshlet_culling(c, &name, &asset, 2000);
    }
    // A dense character: ~4,000 meshlets over 33 joints, 250 instances ≈ 1M meshlets.
    let demo = skinlet::demo::demo_character(&skinlet::demo::DemoParams { triangles: 500_000, ..Default::default() });
    meshlet_culling(c, "demo-500k", &demo, 250);
}

criterion_group!(culling_benches, benches);
criterion_main!(culling_benches);
