//! The baker's tests on the demo character (skinlet-lab's generator: a whole character with
//! two skins, rigid, animated and instanced parts, a morph face and three clips), one module
//! per baker module they test.

mod common;

mod bake {
    use glam::Vec3;
    use skinlet::bake::*;
    use skinlet::bounds::envelope::Envelope;
    use skinlet::bounds::refine::Refinement;
    use skinlet::contour::skinned::{SkinnedParams, skinned_edges};
    use skinlet::meshlet::{Builder, MeshletLimits};
    use skinlet::overdraw::cluster::ClusterParams;
    use skinlet_lab::demo::{DemoParams, demo_character};
    use skinlet_runtime::bake_view::BakeView;

    /// The bake file's header and section-table entry sizes (docs/FORMAT.md).
    const HEADER: usize = 16;
    const ENTRY: usize = 24;

    fn baked() -> Baked {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let clips: Vec<_> = asset.clips.iter().collect();
        let how = Refinement { max_rounds: 3, ..Refinement::NONE };
        bake(&asset, &asset.character().unwrap(), &clips, Builder::SkinAware, MeshletLimits::NVIDIA, &how, &mut |_| {})
            .unwrap()
            .0
    }

    #[test]
    fn same_input_same_bytes() {
        assert_eq!(to_bytes(&baked()), to_bytes(&baked()));
    }

    #[test]
    fn overdraw_orders_round_trip_and_are_checked() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let params = ClusterParams { k: 3, view_levels: 1, iterations: 2, ..ClusterParams::default() };
        add_overdraw(&mut b, &asset, &params, 3).unwrap();
        let bytes = to_bytes(&b);
        let back = from_bytes(&bytes).unwrap();
        assert_eq!(back, b);
        let o = back.overdraw.as_ref().unwrap();
        assert_eq!(o.buffers.len(), 3);
        assert_eq!(o.keyframes.len(), 3 * asset.clips.len().min(b.settings.clips.len()));
        // A stored keyframe seen from a stored viewpoint selects a valid buffer.
        assert!(o.select(0, o.keyframes[0].1, o.framing.center + glam::Vec3::Z) < 3);
        // Every buffer keeps each part's triangles in the part's range, reordered within it.
        let mut reordered = 0;
        for buffer in &o.buffers {
            for p in &b.parts {
                let range = p.triangles.start as usize..p.triangles.end as usize;
                assert!(buffer[range.clone()].iter().flatten().all(|v| p.vertices.contains(v)), "{p:?}");
                reordered += (buffer[range.clone()] != b.mesh.triangles[range]) as usize;
            }
        }
        assert!(reordered > 0, "no part was reordered");
        // Damage the last buffer's first index: no longer a reordering, refused.
        let table = o.lookup.table.len().next_multiple_of(4);
        let n = b.mesh.triangles.len();
        let at = section_end(&bytes, b"OVDR") - table - 12 * n;
        let mut bad = bytes.clone();
        bad[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
        bad[at + 4..at + 8].copy_from_slice(&0u32.to_le_bytes());
        let e = from_bytes(&bad).unwrap_err().to_string();
        assert!(e.contains("OVDR") && e.contains("not a reordering"), "{e}");
    }

    #[test]
    fn contours_round_trip_extract_like_before_and_are_checked() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let how = Refinement { max_rounds: 1, ..Refinement::NONE };
        let params = SkinnedParams::new(skinlet::contour::skinned::SkinnedMethod::Animated, how);
        add_contours(&mut b, &asset, &params, true).unwrap();
        let c = b.contours.as_ref().unwrap();
        assert!(c.patches.patches.len() > 10, "{}", c.patches.patches.len());
        let bytes = to_bytes(&b);
        let back = from_bytes(&bytes).unwrap();
        assert_eq!(back, b);
        // The stored patches extract what brute force finds, on the rest pose from outside.
        let edges = skinned_edges(&back.mesh, true).unwrap();
        let globals: Vec<glam::DMat4> = back.inverse_bind.iter().map(|m| m.inverse().as_dmat4()).collect();
        let view = skinlet::contour::Projection::Perspective { eye: Vec3::new(0.5, 1.0, 4.0) };
        let (mut want, mut got) = (Vec::new(), Vec::new());
        skinlet::contour::brute_force(&back.mesh.positions, &edges, view, &mut want);
        back.contours.as_ref().unwrap().patches.extract(&back.mesh.positions, &edges, &globals, None, view, &mut got);
        got.sort_unstable();
        assert!(!want.is_empty());
        assert_eq!(got, want);
        // Damage: the last window bound's sine out of range.
        let mut bad = bytes.clone();
        let n = section_end(&bytes, b"CONT");
        bad[n - 8..n - 4].copy_from_slice(&2f32.to_le_bytes());
        let e = from_bytes(&bad).unwrap_err().to_string();
        assert!(e.contains("CONT") && e.contains("window bound"), "{e}");
    }

    /// `lod`'s cuts (read back from `b`'s bytes) at every threshold of `thresholds`, 0 and
    /// `f32::MAX` have the mesh's boundary: no cracks.
    fn cuts_keep_the_boundary(
        b: &Baked,
        lod: &skinlet_runtime::bake_view::LodView,
        thresholds: impl Iterator<Item = f32>,
    ) {
        let clusters = &b.lod.as_ref().unwrap().meshlets;
        // A cluster's triangles, numbered as the view numbers them (meshlets first).
        let cluster_triangles = |c: usize| -> Vec<[u32; 3]> {
            let (m, i) = if c < b.meshlets.len() { (&b.meshlets, c) } else { (clusters, c - b.meshlets.len()) };
            m.mesh_triangles(&m.meshlets[i]).collect()
        };
        let whole = super::common::boundary(b.mesh.triangles.iter().copied());
        let mut cut = Vec::new();
        for t in thresholds.chain([0.0, f32::MAX]) {
            lod.cut(t, &mut cut);
            let found = super::common::boundary(cut.iter().flat_map(|&c| cluster_triangles(c as usize)));
            assert!(found == whole, "threshold {t}");
        }
    }

    #[test]
    fn lod_round_trips_every_cut_keeps_the_part_boundaries_and_is_checked() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        add_lod(&mut b, &asset, &skinlet::meshlet::lod::LodParams::default()).unwrap();
        let l = b.lod.as_ref().unwrap();
        assert!(l.groups.len() >= b.parts.len() && !l.clusters.is_empty(), "{} groups", l.groups.len());
        let bytes = to_bytes(&b);
        assert_eq!(from_bytes(&bytes).unwrap(), b);
        let view = BakeView::new(&bytes).unwrap();
        let v = view.lod().unwrap();
        let meshlets = view.meshlets();
        cuts_keep_the_boundary(&b, v, l.groups.iter().map(|g| g.1));
        let mut cut = Vec::new();
        v.cut(0.0, &mut cut);
        assert_eq!(cut.len(), meshlets.len(), "threshold 0 draws the meshlets");
        // Damaged: counts, a group's error, a cluster's parent.
        let lodc = section(&bytes, b"LODC");
        let damaged = |at: usize, value: [u8; 4], want: &str| {
            let mut bad = bytes.clone();
            bad[lodc.start + at..lodc.start + at + 4].copy_from_slice(&value);
            let e = from_bytes(&bad).unwrap_err().to_string();
            assert!(e.contains("LODC") && e.contains(want), "{want}: {e}");
        };
        let (g, m) = (l.groups.len(), l.base_parents.len());
        damaged(8, (m as u32 + 1).to_le_bytes(), "meshlets");
        damaged(16 + 4, f32::NAN.to_le_bytes(), "group 0");
        damaged(16 + 4, (-1.0f32).to_le_bytes(), "group 0");
        let root = l.clusters.iter().position(|c| c[1] == skinlet_runtime::bake_view::NO_GROUP).unwrap();
        let parent_at = 16 + 8 * g + 4 * m + 8 * root + 4;
        damaged(parent_at, (g as u32).to_le_bytes(), &format!("cluster {root}: parent group"));
        damaged(parent_at, l.clusters[root][0].to_le_bytes(), &format!("cluster {root}: parent group"));
        assert!(from_bytes(&bytes[..lodc.end - 4]).is_err());
    }

    #[test]
    fn lod_within_the_envelope_round_trips_keeps_the_boundaries_and_is_checked() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let clips: Vec<_> = asset.clips.iter().collect();
        let envelope = Envelope::from_clips(&asset.skeleton, &b.palette(), &b.mesh, &clips, 0.1).unwrap();
        add_envelope(&mut b, &asset, envelope.clone()).unwrap();
        add_lod(&mut b, &asset, &skinlet::meshlet::lod::LodParams::default()).unwrap();
        let l = b.lod.as_ref().unwrap();
        let e = l.envelope.as_ref().expect("a bake with an envelope gets LOD errors within it");
        assert_eq!((e.errors.len(), e.bounds.len()), (l.groups.len(), l.clusters.len()));
        // The envelope added after the hierarchy, then its LOD errors: the same errors and bounds.
        let mut later = baked();
        add_lod(&mut later, &asset, &skinlet::meshlet::lod::LodParams::default()).unwrap();
        add_envelope(&mut later, &asset, envelope).unwrap();
        assert!(later.lod.as_ref().unwrap().envelope.is_none(), "an envelope added later has no LOD errors yet");
        add_lod_envelope(&mut later, &asset).unwrap();
        assert_eq!(later.lod.as_ref().unwrap().envelope.as_ref(), Some(e));
        let bytes = to_bytes(&b);
        assert_eq!(from_bytes(&bytes).unwrap(), b);
        let view = BakeView::new(&bytes).unwrap();
        let v = view.lod().unwrap().envelope().unwrap();
        assert!(view.lod_envelope_culler().unwrap().is_some());
        cuts_keep_the_boundary(&b, &v, e.errors.iter().copied());
        // Damaged: counts, a level, an error, a parent's error below its child's, the
        // section without ENVL.
        let lode = section(&bytes, b"LODE");
        let damaged = |at: usize, value: [u8; 4], want: &str| {
            let mut bad = bytes.clone();
            bad[lode.start + at..lode.start + at + 4].copy_from_slice(&value);
            let e = from_bytes(&bad).unwrap_err().to_string();
            assert!(e.contains("LODE") && e.contains(want), "{want}: {e}");
        };
        let g = l.groups.len() as u32;
        damaged(0, (g + 1).to_le_bytes(), "groups");
        damaged(16, (l.groups[0].0 + 1).to_le_bytes(), "group 0: level");
        damaged(16 + 4, f32::INFINITY.to_le_bytes(), "group 0");
        let (c, &[own, parent]) = (l.clusters.iter().enumerate())
            .find(|(_, c)| c[1] != skinlet_runtime::bake_view::NO_GROUP && e.errors[c[0] as usize] > 0.0)
            .expect("a cluster with a parent and an error");
        assert!(e.errors[own as usize] > 0.0);
        damaged(16 + 8 * parent as usize + 4, 0f32.to_le_bytes(), &format!("cluster {}", b.meshlets.len() + c));
        let table_entry = bytes.windows(4).position(|w| w == b"ENVL").unwrap();
        let mut bad = bytes.clone();
        bad[table_entry..table_entry + 4].copy_from_slice(b"XNVL");
        let err = from_bytes(&bad).unwrap_err().to_string();
        assert!(err.contains("LODE") && err.contains("ENVL"), "{err}");
        assert!(from_bytes(&bytes[..lode.end - 4]).is_err());
    }

    #[test]
    fn part_windows_round_trip_and_are_checked() {
        let b = baked();
        let w = b.part_windows.as_ref().expect("a bake with clips has part windows");
        assert_eq!((w.anchors.len(), w.clips.len()), (b.parts.len(), b.settings.clips.len()));
        assert_eq!(w.boxes.len(), b.parts.len() * w.windows());
        let bytes = to_bytes(&b);
        assert_eq!(from_bytes(&bytes).unwrap().part_windows.as_ref(), Some(w));
        let pwin = section(&bytes, b"PWIN");
        let damaged = |at: usize, value: [u8; 4], want: &str| {
            let mut bad = bytes.clone();
            bad[pwin.start + at..pwin.start + at + 4].copy_from_slice(&value);
            let e = from_bytes(&bad).unwrap_err().to_string();
            assert!(e.contains("PWIN") && e.contains(want), "{want}: {e}");
        };
        let (clips, parts) = (w.clips.len(), w.anchors.len());
        damaged(0, (parts as u32 + 1).to_le_bytes(), "parts");
        damaged(16 + 8, 0u32.to_le_bytes(), "clip 0: windows");
        damaged(16 + 16 * clips, (b.inverse_bind.len() as u32).to_le_bytes(), "anchor");
        damaged(pwin.len() - 4, f32::NAN.to_le_bytes(), "non-finite");
        damaged(pwin.len() - 4, (-1e30f32).to_le_bytes(), "box");
        assert!(from_bytes(&bytes[..pwin.end - 4]).is_err());
        // Window counts whose sum wraps around u32 to the right total (clip 0: 2³² − 1
        // windows; clip 1 from there, ending where clip 2 starts): refused, not a panic and
        // not windows of one part read as another's.
        assert!(clips >= 2, "the demo has several clips");
        let next = if clips > 2 { w.clips[2].first } else { w.windows() as u32 };
        let mut bad = bytes.clone();
        let mut put = |at: usize, x: u32| bad[pwin.start + at..pwin.start + at + 4].copy_from_slice(&x.to_le_bytes());
        put(16 + 8, u32::MAX);
        put(16 + 16 + 12, u32::MAX);
        put(16 + 16 + 8, next.wrapping_add(1));
        let e = from_bytes(&bad).unwrap_err().to_string();
        assert!(e.contains("PWIN") && e.contains("clip 0: windows"), "{e}");
    }

    /// Byte offset of meshlet `i`'s `BNDS` record.
    fn bnds_record(bytes: &[u8], i: usize) -> usize {
        section_start(bytes, b"BNDS") + 16 + 48 * i
    }

    #[test]
    fn drivers_past_16_bits_are_refused() {
        // 65,541 drivers (identity inverse binds), and a meshlet whose principal joint is
        // 65,541 − 1: a u16 would read it as joint 4.
        let mut b = baked();
        let extra = 65_541 - b.inverse_bind.len();
        b.inverse_bind.extend(std::iter::repeat_n(glam::Mat4::IDENTITY, extra));
        b.joint_nodes.extend(std::iter::repeat_n(0, extra));
        b.joint_names.extend(std::iter::repeat_n(String::new(), extra));
        let mut bytes = to_bytes(&b);
        let at = bnds_record(&bytes, 0) + 40;
        bytes[at..at + 4].copy_from_slice(&65_540u32.to_le_bytes());
        let e = from_bytes(&bytes).unwrap_err().to_string();
        assert!(e.contains("SKIN") && e.contains("65,536"), "{e}");
    }

    #[test]
    fn cone_axes_and_angles_are_checked() {
        let b = baked();
        let bytes = to_bytes(&b);
        let coned = b.bounds.iter().position(|x| x.cone_angle < std::f32::consts::FRAC_PI_2).expect("a cone");
        let damaged = |at: usize, value: f32, want: &str| {
            let mut bad = bytes.clone();
            bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
            let e = from_bytes(&bad).unwrap_err().to_string();
            assert!(e.contains("BNDS") && e.contains(want), "{want}: {e}");
        };
        // The cone axis 100 times too long; a rest cone angle past π.
        let axis = bnds_record(&bytes, coned) + 16;
        damaged(axis, b.bounds[coned].cone_axis.x * 100.0 + 100.0, "axis");
        damaged(bnds_record(&bytes, coned) + 36, 4.0, "rest cone angle");
    }

    #[test]
    fn contour_patch_cones_are_checked() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let how = skinlet::contour::skinned::refinement(None, 0);
        let sp = SkinnedParams::new(skinlet::contour::skinned::SkinnedMethod::Animated, how);
        add_contours(&mut b, &asset, &sp, true).unwrap();
        let bytes = to_bytes(&b);
        let patches = &b.contours.as_ref().unwrap().patches.patches.bounds;
        let coned = patches.iter().position(|p| p.cos_angle > 0.1).expect("a patch with a cone");
        let record = section_start(&bytes, b"CONT") + 64 + 48 * coned;
        let damaged = |at: usize, value: f32| {
            let mut bad = bytes.clone();
            bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
            let e = from_bytes(&bad).unwrap_err().to_string();
            assert!(e.contains("CONT") && e.contains(&format!("patch {coned}")), "{e}");
        };
        damaged(record + 16, patches[coned].axis.x * 100.0 + 100.0);
        // A sine that is not the cosine's.
        damaged(record + 28, (patches[coned].sin_angle * 0.5).max(0.01));
    }

    #[test]
    fn many_sections_are_read_and_a_repeated_tag_far_apart_is_found() {
        // 100,000 empty sections with distinct tags, then one that repeats the first.
        let n = 100_001;
        let mut bytes = vec![0u8; 16 + 24 * n];
        bytes[..8].copy_from_slice(&skinlet::bake::MAGIC);
        bytes[8..12].copy_from_slice(&skinlet::bake::VERSION.to_le_bytes());
        bytes[12..16].copy_from_slice(&(n as u32).to_le_bytes());
        for k in 0..n {
            let e = 16 + 24 * k;
            let tag = (k % (n - 1)) as u32 + 0x4141_4141;
            bytes[e..e + 4].copy_from_slice(&tag.to_le_bytes());
            bytes[e + 8..e + 16].copy_from_slice(&16u64.to_le_bytes());
        }
        let words: Vec<u32> = bytes.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
        let Err(e) = BakeView::new(bytemuck::cast_slice(&words)) else { panic!("a repeated tag was accepted") };
        let e = e.to_string();
        assert!(e.contains("twice") && e.contains("entries 0 and 100000"), "{e}");
        let distinct = &bytemuck::cast_slice::<u32, u8>(&words)[..16 + 24 * (n - 1)];
        let mut head = distinct.to_vec();
        head[12..16].copy_from_slice(&((n - 1) as u32).to_le_bytes());
        let words: Vec<u32> = head.chunks(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect();
        // The table passes; the sections' checks come next (these have none of the format's).
        let e = BakeView::new(bytemuck::cast_slice(&words)).unwrap_err().to_string();
        assert!(e.contains("section INFO is missing"), "{e}");
    }

    #[test]
    fn round_trip_is_exact_and_bytes_are_aligned() {
        let b = baked();
        let bytes = to_bytes(&b);
        assert_eq!(from_bytes(&bytes).unwrap(), b);
        assert_eq!(to_bytes(&from_bytes(&bytes).unwrap()), bytes);
        // Every section starts 16-byte aligned (GPU uploads straight from the file).
        let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        for i in 0..n {
            let e = HEADER + ENTRY * i;
            assert_eq!(u64::from_le_bytes(bytes[e + 8..e + 16].try_into().unwrap()) % 16, 0);
        }
    }

    #[test]
    fn the_runtime_view_reads_what_the_baker_wrote() {
        // The zero-copy view of skinlet-runtime hands out the bake's own bytes as the bounds,
        // matrices, nodes and envelope read gives, and builds the same cullers and guard; from
        // a misaligned start the view refuses and read goes through an aligned copy.
        use skinlet_runtime::meshlet_cull::MeshletCuller;
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let clips: Vec<_> = asset.clips.iter().collect();
        let envelope = Envelope::from_clips(&asset.skeleton, &b.palette(), &b.mesh, &clips, 0.1).unwrap();
        add_envelope(&mut b, &asset, envelope).unwrap();
        let how = skinlet::contour::skinned::refinement(None, 0);
        let sp = SkinnedParams::new(skinlet::contour::skinned::SkinnedMethod::Animated, how);
        add_contours(&mut b, &asset, &sp, true).unwrap();
        let params = ClusterParams { k: 2, view_levels: 1, iterations: 1, ..ClusterParams::default() };
        add_overdraw(&mut b, &asset, &params, 2).unwrap();
        let bytes = to_bytes(&b);
        let view = BakeView::new(&bytes).unwrap();
        let records = view.meshlet_bounds();
        assert_eq!(records.len(), b.bounds.len());
        for ((r, want), class) in records.iter().zip(&b.bounds).zip(&b.classes) {
            assert_eq!((r.bounds(), r.class()), (*want, *class));
        }
        assert!(std::ptr::eq(records.as_ptr().cast::<u8>(), &bytes[section_start(&bytes, b"BNDS") + 16]), "zero-copy");
        let ibm: Vec<glam::Mat4> = view.inverse_bind().iter().map(glam::Mat4::from_cols_array).collect();
        assert_eq!(ibm, b.inverse_bind);
        assert_eq!(view.joint_nodes(), &b.joint_nodes[..]);
        // Vertices, triangles and meshlets as slices of the file, and the meshlet index buffer.
        let v = view.vertices();
        let inf = b.mesh.influences.as_ref().unwrap();
        assert_eq!((v.positions, v.normals), (&b.mesh.positions[..], &b.mesh.normals[..]));
        assert_eq!((v.stride, v.joints, v.weights), (inf.stride, &inf.joints[..], &inf.weights[..]));
        assert_eq!(view.triangles(), &b.mesh.triangles[..]);
        let (indices, draws) = view.meshlets().index_buffer();
        let mut first = 0;
        for (m, draw) in b.meshlets.meshlets.iter().zip(&draws) {
            let local = &b.meshlets.triangles[m.triangle_offset as usize..][..3 * m.triangle_count as usize];
            let verts = &b.meshlets.vertices[m.vertex_offset as usize..];
            assert_eq!(*draw, [local.len() as u32, first]);
            assert!(local.iter().zip(&indices[first as usize..]).all(|(&l, &i)| verts[l as usize] == i));
            first += local.len() as u32;
        }
        assert_eq!((draws.len(), indices.len()), (b.meshlets.len(), first as usize));
        let culler = MeshletCuller::new(&b.bounds, &b.classes, b.inverse_bind.len()).unwrap();
        assert_eq!(view.culler().unwrap().slots(), culler.slots());
        // Part 0 drawn two-sided: its meshlets (and only those) are never backface-culled.
        let two_sided = view.meshlets_of_parts(&[true]);
        let part = view.parts()[0].meshlets;
        assert!((0..b.meshlets.len()).all(|m| two_sided[m] == (part[0] as usize..part[1] as usize).contains(&m)));
        let slots = culler.slots();
        assert!(slots.iter().any(|s| two_sided[s.id as usize] && s.sin <= 1.0), "no cone in part 0 to test");
        for (s, t) in slots.iter().zip(view.two_sided_culler(&[true]).unwrap().slots()) {
            let no_cone = skinlet_runtime::meshlet_cull::CullSlot { axis: glam::Vec3::ZERO, sin: 2.0, ..*s };
            let want = if two_sided[s.id as usize] { no_cone } else { *s };
            assert_eq!(t, want);
        }
        let (e, ev) = (b.envelope.as_ref().unwrap(), view.envelope().unwrap());
        assert_eq!(ev.guard().unwrap(), e.envelope.guard().unwrap());
        assert_eq!(ev.any_pose(), e.any_pose);
        let culler = MeshletCuller::new(&e.bounds, &e.classes, b.inverse_bind.len()).unwrap();
        let culler = culler.with_any_pose(&e.any_pose).unwrap();
        let from_view = ev.culler(b.inverse_bind.len()).unwrap();
        assert_eq!((from_view.slots(), from_view.any_pose_boxes()), (culler.slots(), culler.any_pose_boxes()));
        // Morph targets as slices of the file; contour patches with the edges they index.
        let (m, mv) = (&b.mesh.morphs, view.morphs().unwrap());
        assert!(!m.deltas.is_empty());
        assert!(std::ptr::eq(mv.weights.as_ptr().cast::<u8>(), &bytes[section_start(&bytes, b"MRPH") + 8]));
        assert_eq!((mv.weights, mv.offsets, mv.deltas), (&m.weights[..], &m.offsets[..], &m.deltas[..]));
        // INFO's clips, PART's records in place, OVDR's orders.
        assert_eq!(view.info().clips, b.settings.clips);
        let parts = view.parts();
        assert!(std::ptr::eq(parts.as_ptr().cast::<u8>(), &bytes[section_start(&bytes, b"PART") + 4]));
        let ranges =
            |p: &BakedPart| [p.vertices.clone(), p.triangles.clone(), p.meshlets.clone()].map(|r| [r.start, r.end]);
        assert!(parts.iter().zip(&b.parts).all(|(r, p)| [r.vertices, r.triangles, r.meshlets] == ranges(p)));
        assert_eq!((parts.len(), view.overdraw_orders()), (b.parts.len(), b.overdraw.as_ref()));
        let (contours, edges) = view.contours().unwrap();
        assert_eq!(Some(contours), b.contours.as_ref());
        assert_eq!(*edges, skinned_edges(&b.mesh, true).unwrap());
        assert!(edges.dropped_concave > 0, "the demo has concave rigid quads to leave out");
        let mut shifted = vec![0u8; bytes.len() + 1];
        shifted[1..].copy_from_slice(&bytes);
        assert!(BakeView::new(&shifted[1..]).unwrap_err().to_string().contains("aligned"));
        assert_eq!(from_bytes(&shifted[1..]).unwrap(), b);
    }

    /// Where section `tag` starts and ends in bake bytes (from the section table).
    fn section(bytes: &[u8], tag: &[u8; 4]) -> std::ops::Range<usize> {
        let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let e = (0..n).map(|i| HEADER + i * ENTRY).find(|&e| &bytes[e..e + 4] == tag).expect("the section");
        let at = |k: usize| u64::from_le_bytes(bytes[e + k..e + k + 8].try_into().unwrap()) as usize;
        at(8)..at(8) + at(16)
    }

    fn section_start(bytes: &[u8], tag: &[u8; 4]) -> usize {
        section(bytes, tag).start
    }

    fn section_end(bytes: &[u8], tag: &[u8; 4]) -> usize {
        section(bytes, tag).end
    }

    #[test]
    fn every_truncation_and_many_corruptions_give_errors_not_panics() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let params = ClusterParams { k: 3, view_levels: 1, iterations: 2, ..ClusterParams::default() };
        add_overdraw(&mut b, &asset, &params, 3).unwrap();
        let how = skinlet::contour::skinned::refinement(None, 0);
        let sp = SkinnedParams::new(skinlet::contour::skinned::SkinnedMethod::Animated, how);
        add_contours(&mut b, &asset, &sp, true).unwrap();
        let clips: Vec<_> = asset.clips.iter().collect();
        let envelope = Envelope::from_clips(&asset.skeleton, &b.palette(), &b.mesh, &clips, 0.1).unwrap();
        add_envelope(&mut b, &asset, envelope).unwrap();
        add_lod(&mut b, &asset, &skinlet::meshlet::lod::LodParams::default()).unwrap();
        let bytes = to_bytes(&b);
        let back = from_bytes(&bytes).unwrap();
        assert_eq!(back, b, "every section round-trips");
        check_consumers(&back).unwrap();
        for cut in 0..bytes.len() {
            assert!(from_bytes(&bytes[..cut]).is_err(), "truncated at {cut} was accepted");
        }
        let mut rng = 0x9E3779B97F4A7C15u64;
        let mut accepted = 0;
        for _ in 0..3000 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let mut b = bytes.clone();
            let at = (rng % b.len() as u64) as usize;
            b[at] ^= 1 << (rng >> 60 & 7);
            // The runtime view and the baker's reader accept the same files: the reader goes
            // through the view, then checks that the meshlets hold exactly the triangles.
            let view = BakeView::new(&b);
            // Many flips (e.g. in a float's low bits) are valid: those must run everywhere.
            if let Ok(back) = from_bytes(&b) {
                check_consumers(&back).unwrap();
                assert!(view.unwrap().meshlets().index_buffer().1.len() == back.meshlets.len());
                accepted += 1;
            }
        }
        assert!(accepted > 0 && accepted < 3000, "{accepted} of 3000 flipped files accepted");
    }

    #[test]
    fn readers_refuse_what_consumers_cannot_take() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let mut b = baked();
        let params = ClusterParams { k: 2, view_levels: 1, iterations: 1, ..ClusterParams::default() };
        add_overdraw(&mut b, &asset, &params, 2).unwrap();
        let bytes = to_bytes(&b);
        // No keyframes: the lookup would select from an empty table.
        let mut no_keys = bytes.clone();
        let at = section_start(&bytes, b"OVDR") + 4;
        no_keys[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
        let e = from_bytes(&no_keys).unwrap_err().to_string();
        assert!(e.contains("OVDR") && e.contains("0 keyframes"), "{e}");
        // No joints: every meshlet's principal joint is out of range.
        let mut no_joints = bytes.clone();
        let at = section_start(&bytes, b"SKIN");
        no_joints[at..at + 4].copy_from_slice(&0u32.to_le_bytes());
        assert!(from_bytes(&no_joints).is_err());
        // More buffers than a bake holds, and culler inputs that do not match.
        let many = ClusterParams { k: 256, ..params };
        assert!(add_overdraw(&mut b, &asset, &many, 2).unwrap_err().to_string().contains("256 overdraw buffers"));
        let culler = skinlet_runtime::meshlet_cull::MeshletCuller::new(&b.bounds, &b.classes[1..], b.joint_nodes.len());
        assert!(culler.is_err());
        assert!(skinlet_runtime::meshlet_cull::MeshletCuller::new(&b.bounds, &b.classes, 0).is_err());
    }

    #[test]
    fn errors_say_what_and_where() {
        let b = baked();
        let mut bytes = to_bytes(&b);
        let msg = |bytes: &[u8]| from_bytes(bytes).unwrap_err().to_string();
        let mut wrong = bytes.clone();
        wrong[0] = b'X';
        assert!(msg(&wrong).contains("magic"), "{}", msg(&wrong));
        let mut newer = bytes.clone();
        newer[8] = VERSION as u8 + 1;
        let m = msg(&newer);
        assert!(m.contains(&format!("version {}", VERSION + 1)), "{m}");
        // A triangle index past the vertex count, in section TRIS.
        let tris = u64::from_le_bytes(bytes[HEADER + 3 * ENTRY + 8..HEADER + 3 * ENTRY + 16].try_into().unwrap());
        let at = tris as usize + 4;
        bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let m = msg(&bytes);
        assert!(m.contains("TRIS") && m.contains("triangle 0 [4294967295") && m.contains("indexes past"), "{m}");
        // The demo's face is in MRPH: a delta naming a weight that does not exist.
        assert!(!b.mesh.morphs.is_empty());
        let mut bytes = to_bytes(&b);
        let start = section_start(&bytes, b"MRPH");
        let mo = &b.mesh.morphs;
        let first_delta = start + 8 + 12 * mo.weights.len() + 4 * mo.offsets.len();
        bytes[first_delta..first_delta + 4].copy_from_slice(&9u32.to_le_bytes());
        let m = msg(&bytes);
        assert!(m.contains("MRPH") && m.contains("a delta uses weight 9 of 2"), "{m}");
        assert_eq!(from_bytes(&to_bytes(&b)).unwrap().mesh.morphs, b.mesh.morphs, "read back as written");
    }
}

mod character {
    use skinlet::character::*;
    use skinlet::model::{Instance, Node, Skeleton, Trs};
    use skinlet_lab::demo::{DemoParams, demo_character};

    #[test]
    fn scenes_choose_the_parts() {
        // The demo plus a second root node drawing the eye mesh, in scene 1 only.
        let mut a = demo_character(&DemoParams { triangles: 1000, ..DemoParams::default() });
        let mut nodes = a.skeleton.nodes.clone();
        nodes.push(Node { name: "lamp".into(), parent: None, rest: Trs::IDENTITY, matrix: None });
        let lamp = nodes.len() as u32 - 1;
        a.skeleton = Skeleton::new(nodes).unwrap();
        a.instances.push(Instance { node: lamp, mesh: 4, skin: None });
        // No scenes: every root is drawn.
        assert_eq!(character(&a, None).unwrap().parts.len(), 7);
        a.scenes = vec![vec![0], vec![lamp]];
        a.default_scene = Some(1);
        let nodes = |c: Character| c.parts.iter().map(|p| p.node).collect::<Vec<_>>();
        assert_eq!(nodes(character(&a, None).unwrap()), [lamp]);
        assert_eq!(character(&a, Some(0)).unwrap().parts.len(), 6);
        let e = character(&a, Some(2)).unwrap_err().to_string();
        assert!(e.contains("scene 2 does not exist (the file has 2)"), "{e}");
        a.scenes.push(Vec::new());
        let e = character(&a, Some(2)).unwrap_err().to_string();
        assert!(e.contains("no node of scene 2 draws a triangle mesh"), "{e}");
    }

    #[test]
    fn a_selection_poses_like_its_parts_in_the_whole() {
        let a = demo_character(&DemoParams { triangles: 1000, ..DemoParams::default() });
        let whole = a.character().unwrap();
        // The body (morph face) and the propeller (animated rigid node).
        let some = whole.select(|i, _| i == 0 || i == 3).unwrap();
        assert_eq!(some.parts.iter().map(|p| p.node).collect::<Vec<_>>(), [whole.parts[0].node, whole.parts[3].node]);
        assert!(!some.mesh.morphs.is_empty() && some.mesh.morphs.weights == whole.mesh.morphs.weights);
        let clip = &a.clips[2];
        let ((all, _), (sel, _)) =
            (whole.posed(&a.skeleton, Some(clip), 0.7).unwrap(), some.posed(&a.skeleton, Some(clip), 0.7).unwrap());
        for (p, q) in [&whole.parts[0], &whole.parts[3]].into_iter().zip(&some.parts) {
            let range = |p: &Part| p.vertices.start as usize..p.vertices.end as usize;
            assert_eq!(all[range(p)], sel[range(q)]);
            let tris = |c: &Character, p: &Part| -> Vec<[u32; 3]> {
                let t = &c.mesh.triangles[p.triangles.start as usize..p.triangles.end as usize];
                t.iter().map(|t| t.map(|i| i - p.vertices.start)).collect()
            };
            assert_eq!(tris(&whole, p), tris(&some, q));
        }
        assert!(whole.select(|_, _| false).is_err());
    }
}

mod refine {
    use skinlet::bounds::refine::*;
    use skinlet::bounds::sphere_cone::meshlet_bounds;
    use skinlet::bounds::verify::verify_bounds;
    use skinlet::clip::Clip;
    use skinlet::meshlet::{Builder, MeshletLimits, build};
    use skinlet_lab::demo::{DemoParams, demo_character};
    use std::time::Duration;

    #[test]
    fn refinement_tightens_stays_conservative_and_is_deterministic() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let character = asset.character().unwrap();
        let skin = &character.palette;
        let prepared = skinlet::bake::prepare_character(&character).unwrap();
        let meshlets = build(&prepared, Builder::SkinAware, MeshletLimits::NVIDIA).unwrap();
        let clips: Vec<&Clip> = asset.clips.iter().collect();
        let keys = meshlet_bounds(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets).unwrap();
        let how = Refinement { max_rounds: 40, ..Refinement::NONE };
        let a = refine(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &how).unwrap();
        let b = refine(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &how).unwrap();
        assert_eq!(a, b, "same rounds, same bounds");
        assert_eq!((a.rounds, a.stop), (40, Stop::Rounds));
        let mut tighter = 0;
        for (r, k) in a.bounds.iter().zip(&keys) {
            assert!(r.radius <= k.radius && r.cone_angle <= k.cone_angle, "refined {r:?} looser than {k:?}");
            tighter += (r.radius < k.radius || r.cone_angle < k.cone_angle) as usize;
        }
        assert!(tighter > keys.len() / 4, "only {tighter} of {} meshlets tightened", keys.len());
        let report = verify_bounds(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &a.bounds, 100).unwrap();
        assert_eq!(report.violations(), 0, "{report:?}");
        assert!(report.mean_radius_ratio >= 1.0 - 1e-5);

        let unlimited = Refinement { max_rounds: usize::MAX, ..Refinement::NONE };
        let done = refine(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &unlimited).unwrap();
        assert_eq!(done.stop, Stop::Converged);
        let out_of_time = Refinement { budget: Some(Duration::ZERO), ..unlimited };
        let cut = refine(&asset.skeleton, skin, &clips, &prepared.mesh, &meshlets, &out_of_time).unwrap();
        assert_eq!((cut.rounds, cut.stop, &cut.bounds), (0, Stop::Budget, &keys));
    }
}

mod joint_aabb {
    use glam::Vec3;
    use skinlet::cull::joint_aabb::*;
    use skinlet::pose::{Poser, skinning_matrices};
    use skinlet_lab::demo::{DemoParams, demo_character};

    #[test]
    fn policies_give_what_they_promise() {
        let asset = demo_character(&DemoParams { triangles: 2000, ..DemoParams::default() });
        let character = asset.character().unwrap();
        let (skin, mesh) = (&character.palette, character.mesh.clone());
        let dynamic = joint_boxes(&mesh, skin, JointSpace::Mesh, &asset.clips.iter().collect::<Vec<_>>()).unwrap();
        let bind_pose = points_box(&mesh.positions);
        let mut poser = Poser::default();
        let clip = &asset.clips[0];
        let globals = poser.globals(&asset.skeleton, Some(clip), clip.start + 0.37 * clip.duration()).to_vec();
        let mut skinning = Vec::new();
        skinning_matrices(skin, &globals, &mut skinning);
        let mut joint_globals = Vec::new();
        skinlet::pose::joint_globals(skin, &globals, &mut joint_globals);
        let mut skinned = vec![Vec3::ZERO; mesh.positions.len()];
        skinlet::skinning::skin(
            mesh.influences.as_ref().unwrap(),
            &mesh.positions,
            &[],
            &skinning,
            &mut skinned,
            &mut [],
        )
        .unwrap();
        let box_of = |p: Policy| p.entity_box(&dynamic, &skinning, &joint_globals, bind_pose);
        let d = box_of(Policy::Dynamic).unwrap();
        assert!(skinned.iter().all(|&p| d.contains(p)), "dynamic boxes hold");
        // The bind-pose box does not follow the animation: some vertex leaves it (why engines
        // that use it cull characters whose limbs are on screen).
        let b = box_of(Policy::BindPose).unwrap();
        assert!(skinned.iter().any(|&p| !b.contains(p)), "the walk should leave the bind-pose box");
        let (min, max) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        assert_eq!(box_of(Policy::Fixed { min, max }), Some(Box3 { min, max }));
        let rel = box_of(Policy::FixedJointRelative { joint: 3, min, max }).unwrap();
        assert!(rel.contains(Vec3::from(joint_globals[3].translation)));
        assert_eq!(box_of(Policy::NoCulling), None);
    }
}

mod export {
    use skinlet_lab::demo::{DemoParams, demo_character};

    #[test]
    fn the_demo_reads_back_as_written() {
        let a = demo_character(&DemoParams { triangles: 1000, ..DemoParams::default() });
        let bytes = skinlet::export::to_glb(&a).unwrap();
        let b = skinlet::import::load_gltf_slice(&bytes, None).unwrap();
        assert!(a.skeleton == b.skeleton && a.skins == b.skins && a.instances == b.instances);
        // The importer renormalizes weights whose f32 sum is not exactly 1: equal to rounding.
        for (m, n) in a.meshes.iter().zip(&b.meshes) {
            assert!(m.weights == n.weights && m.primitives[0].targets == n.primitives[0].targets, "{}", m.name);
            let (g, h) = (&m.primitives[0].geometry, &n.primitives[0].geometry);
            assert!(g.positions == h.positions && g.normals == h.normals && g.triangles == h.triangles, "{}", m.name);
            let (i, j) = (g.influences.as_ref(), h.influences.as_ref());
            assert_eq!(i.map(|i| &i.joints), j.map(|j| &j.joints), "{}", m.name);
            let (wi, wj) = (i.map_or(&[][..], |i| &i.weights[..]), j.map_or(&[][..], |j| &j.weights[..]));
            assert!(wi.len() == wj.len() && wi.iter().zip(wj).all(|(x, y)| (x - y).abs() < 1e-6), "{}", m.name);
        }
        assert_eq!((b.scenes.len(), b.default_scene), (1, Some(0)));
        // An asset's own scenes are written as they are.
        let mut c = a.clone();
        c.scenes = vec![vec![0], vec![0]];
        c.default_scene = Some(1);
        let d = skinlet::import::load_gltf_slice(&skinlet::export::to_glb(&c).unwrap(), None).unwrap();
        assert_eq!((d.scenes, d.default_scene), (c.scenes, c.default_scene));
        assert!(b.report.warnings.is_empty(), "{:?}", b.report.warnings);
        let (ca, cb) = (a.character().unwrap(), b.character().unwrap());
        assert!(ca.parts == cb.parts && ca.palette == cb.palette);
        // Clips: the same channels; the importer renormalizes rotation keys, so poses agree
        // to f32 rounding rather than bit for bit.
        for (x, y) in a.clips.iter().zip(&b.clips) {
            assert_eq!(
                (x.translations.len(), x.rotations.len(), x.scales.len()),
                (y.translations.len(), y.rotations.len(), y.scales.len())
            );
            assert_eq!(x.weights, y.weights, "{}", x.name);
            for k in 0..=8 {
                let t = x.start + x.duration() * k as f32 / 8.0;
                let pose = |asset: &skinlet::Asset, clip| {
                    skinlet::skinning::posed_positions(&asset.skeleton, &ca.palette, &ca.mesh, Some(clip), Some(t))
                        .unwrap()
                };
                let (p, q) = (pose(&a, x), pose(&b, y));
                let worst = p.iter().zip(&q).map(|(u, v)| u.distance(*v)).fold(0f32, f32::max);
                assert!(worst < 1e-5, "{} at {t}: {worst}", x.name);
            }
        }
    }
}

mod cluster {
    use glam::Vec3;
    use skinlet::overdraw::cluster::*;
    use skinlet::overdraw::measure::{Overdraw, Raster};
    use skinlet::overdraw::tipsify::tipsify;

    /// A few keyframes of the demo character's walk (skinned positions) and its triangles.
    fn walk(frames: usize) -> (Vec<Vec<Vec3>>, Vec<[u32; 3]>) {
        let asset =
            skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
        let character = asset.character().unwrap();
        let mesh = character.mesh.clone();
        let (_, keyframes) =
            skinlet::overdraw::evaluate::keyframes(&asset.skeleton, &character.palette, &mesh, &asset.clips[0], frames)
                .unwrap();
        (keyframes, mesh.triangles)
    }

    fn canonical(mut t: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
        for x in &mut t {
            let m = (0..3).min_by_key(|&i| x[i]).unwrap();
            x.rotate_left(m);
        }
        t.sort();
        t
    }

    #[test]
    fn buffers_are_permutations_lookup_matches_and_overdraw_drops() {
        for order in [PatchOrder::Occlusion, PatchOrder::Distance] {
            check_clustering(order);
        }
    }

    fn check_clustering(patch_order: PatchOrder) {
        let (keyframes, triangles) = walk(4);
        let params =
            ClusterParams { k: 3, view_levels: 1, resolution: 48, order: patch_order, ..ClusterParams::default() };
        let c = cluster(&keyframes, &triangles, &params);
        assert_eq!(c, cluster(&keyframes, &triangles, &params), "deterministic");
        let uncached = ClusterParams { cache_bytes: 0, ..params };
        assert_eq!(c, cluster(&keyframes, &triangles, &uncached), "same result without the fragment cache");
        assert_eq!(c.buffers.len(), 3);
        for b in &c.buffers {
            assert_eq!(canonical(b.clone()), canonical(triangles.clone()));
        }
        // The lookup returns the assigned buffer at every stored node's own direction.
        let lookup = lookup(&c, 91, 180);
        let mut agree = 0;
        for f in 0..keyframes.len() {
            for (v, dir) in c.views.iter().enumerate() {
                agree += (lookup.get(f, *dir) == c.assignment[f * c.views.len() + v]) as usize;
            }
        }
        assert_eq!(agree, c.assignment.len(), "the table rounds a stored direction to itself");
        // Overdraw over the nodes: clustered buffers against the vertex-cache order alone.
        let order = tipsify(&triangles, keyframes[0].len(), 16);
        let (mut before, mut after) = (Overdraw::default(), Overdraw::default());
        let mut r = Raster::new(96, 96);
        for (f, pos) in keyframes.iter().enumerate() {
            for (v, dir) in c.views.iter().enumerate() {
                let vp = c.framing.view_proj(c.framing.eye(*dir, 3.0));
                before.add(r.render(pos, &order, &vp));
                after.add(r.render(pos, &c.buffers[c.assignment[f * c.views.len() + v] as usize], &vp));
            }
        }
        eprintln!(
            "{patch_order:?}: overdraw over the nodes: cache order {:.3}, clustered {:.3}",
            before.ratio(),
            after.ratio()
        );
        assert!(after.ratio() < before.ratio(), "clustered {} vs cache order {}", after.ratio(), before.ratio());
    }
}

mod contour {
    use glam::Vec3;
    use skinlet::contour::*;

    #[test]
    fn sphere_contour_is_the_equator_band() {
        // A UV sphere seen from far along +z (and orthographically): contour edges lie
        // near z = 0, and seen from the pole a closed mesh has a closed, non-empty contour.
        let (p, t) = skinlet_lab::demo::uv_sphere(24, 48);
        let edges = Edges::build(&p, &t).unwrap();
        let mut out = Vec::new();
        for proj in
            [Projection::Perspective { eye: Vec3::new(0.0, 0.0, 1e4) }, Projection::Orthographic { dir: Vec3::NEG_Z }]
        {
            let tested = brute_force(&p, &edges, proj, &mut out);
            assert_eq!(tested.edges, edges.quads.len());
            assert!(!out.is_empty());
            for &id in &out {
                let [a, b] = edges.endpoints(id);
                assert!(p[a as usize].z.abs() < 0.14 && p[b as usize].z.abs() < 0.14);
            }
            // Every vertex of a closed contour curve is used by an even number of its edges.
            let mut degree = vec![0; p.len()];
            for &id in &out {
                for v in edges.endpoints(id) {
                    degree[v as usize] += 1;
                }
            }
            assert!(degree.iter().all(|d| d % 2 == 0));
        }
    }
}

mod measure {
    use skinlet::overdraw::measure::*;

    #[test]
    fn overdraw_agrees_with_meshoptimizer_on_axis_views() {
        let asset = skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams {
            triangles: 20_000,
            ..Default::default()
        });
        let mesh = asset.character().unwrap().mesh;
        let mut r = Raster::new(256, 256);
        let adapter = meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(&mesh.positions), 12, 0).unwrap();
        for order in ["as built", "reversed"] {
            let tris: Vec<[u32; 3]> = if order == "reversed" {
                mesh.triangles.iter().rev().copied().collect()
            } else {
                mesh.triangles.clone()
            };
            let flat_order: Vec<u32> = tris.iter().flatten().copied().collect();
            let mut ours = Overdraw::default();
            for v in axis_views(&mesh.positions) {
                ours.add(r.render(&mesh.positions, &tris, &v));
            }
            let theirs = meshopt::analyze_overdraw(&flat_order, &adapter);
            let (a, b) = (ours.ratio(), theirs.overdraw as f64);
            eprintln!(
                "{order}: ours {a:.4} ({} px), meshoptimizer {b:.4} ({} px)",
                ours.covered, theirs.pixels_covered
            );
            assert!((a - b).abs() / b < 0.02, "{order}: ours {a}, meshoptimizer {b}");
            assert!((ours.covered as f64 / theirs.pixels_covered as f64 - 1.0).abs() < 0.02);
        }
    }

    #[test]
    fn fragments_measure_any_order_like_a_render() {
        let asset =
            skinlet_lab::demo::demo_character(&skinlet_lab::demo::DemoParams { triangles: 3000, ..Default::default() });
        let mesh = asset.character().unwrap().mesh;
        let mut r = Raster::new(64, 64);
        let mut frags = Fragments::default();
        let mut depth = Vec::new();
        for (k, vp) in axis_views(&mesh.positions).iter().enumerate() {
            // One group per triangle, then groups of 7 triangles.
            r.fragments(&mesh.positions, &mesh.triangles, &[], vp, &mut frags);
            let n = mesh.triangles.len() as u32;
            let order: Vec<u32> = if k % 2 == 0 { (0..n).collect() } else { (0..n).rev().collect() };
            let tris: Vec<[u32; 3]> = order.iter().map(|&t| mesh.triangles[t as usize]).collect();
            let full = r.render(&mesh.positions, &tris, vp);
            assert_eq!(frags.covered, full.covered);
            assert_eq!(frags.shade(order.iter().copied(), u64::MAX, &mut depth), Some(full.shaded));
            assert_eq!(frags.shade(order.iter().copied(), full.shaded - 1, &mut depth), None);
            let groups: Vec<u32> = (0..n).step_by(7).collect();
            r.fragments(&mesh.positions, &mesh.triangles, &groups, vp, &mut frags);
            let group_order: Vec<u32> = (0..groups.len() as u32).rev().collect();
            let tris: Vec<[u32; 3]> = group_order
                .iter()
                .flat_map(|&g| {
                    &mesh.triangles[groups[g as usize] as usize..(groups[g as usize] as usize + 7).min(n as usize)]
                })
                .copied()
                .collect();
            let full = r.render(&mesh.positions, &tris, vp);
            assert_eq!(frags.covered, full.covered);
            assert_eq!(frags.shade(group_order.iter().copied(), u64::MAX, &mut depth), Some(full.shaded));
        }
    }
}
