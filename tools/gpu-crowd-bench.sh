#!/usr/bin/env bash
# The GPU-driven crowd measured on this machine's GPU: builds skinlet in release, then runs
# `skinlet gpu-bench --json` on the shared characters (Xbot, mannequiny, BrainStem, the demo)
# for the paper's crowd and the dense street-level crowd, per meshlet builder, and prints a
# table of GPU ms per frame, meshlets drawn (frustum + backface, + occlusion, + the triangle
# pass, the oracle, what boxes of the very pose could keep), triangles drawn and draw calls,
# with the adapter's name. Every JSON file stays in the output folder.
#
#   bash tools/gpu-crowd-bench.sh [OUT_DIR]
#
# Settings by environment: INSTANCES_PAPER (64), INSTANCES_DENSE (1024), WIDTH (1280),
# FRAMES (3), REPEATS (3), CHARACTERS ("Xbot mannequiny BrainStem demo"), BUILDERS
# ("skin-aware cone-split meshopt"), SOFTWARE=1 to measure
# lavapipe (labelled as such in the output: the CPU's times, not a GPU's). About 6 minutes on a
# desktop GPU; on lavapipe use smaller settings (docs/GPU.md gives the ones used).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/gpu-crowd-bench}
assets=${SKINLET_ASSETS:-../shared/assets}
mkdir -p "$out"
cargo build --release --locked -p skinlet-cli
skinlet=${CARGO_TARGET_DIR:-target}/release/skinlet
software=()
if [ "${SOFTWARE:-0}" = 1 ]; then software=(--software); fi
common=(--frames "${FRAMES:-3}" --repeats "${REPEATS:-3}" --width "${WIDTH:-1280}" --pipelines VS,VS-indexed
    --budget 0 --rounds 0 --json "${software[@]}")
for name in ${CHARACTERS:-Xbot mannequiny BrainStem demo}; do
    character="$assets/skinned/$name.glb"
    if [ "$name" = demo ]; then character=@demo; fi
    for crowd in paper dense; do
        instances=${INSTANCES_PAPER:-64}
        if [ "$crowd" = dense ]; then instances=${INSTANCES_DENSE:-1024}; fi
        for builder in ${BUILDERS:-skin-aware cone-split meshopt}; do
            file="$out/$name-$crowd-$builder.json"
            echo "gpu-bench $name, $crowd crowd of $instances, $builder meshlets" >&2
            "$skinlet" gpu-bench "$character" --crowd "$crowd" --instances "$instances" --builder "$builder" \
                "${common[@]}" >"$file"
        done
    done
done
# The table: one line per run and row.
node - "$out"/*.json <<'EOF'
const fs = require('fs');
const files = process.argv.slice(2);
let adapter = null;
console.log('| character | crowd | builder | pipeline | culling | GPU ms/frame | meshlets drawn | triangles drawn | vertex refs | oracle | pose box | pose triangles | draws | image |');
console.log('|---|---|---|---|---|---|---|---|---|---|---|---|---|---|');
for (const f of files) {
    const j = JSON.parse(fs.readFileSync(f, 'utf8'));
    adapter = j.adapter;
    const name = f.split('/').pop().replace(/\.json$/, '').split('-')[0];
    for (const r of j.rows) {
        const ms = r.gpu_ms ? r.gpu_ms.median.toFixed(2) : '-';
        console.log(`| ${name} | ${j.crowd} ${j.instances} | ${j.builder} | ${r.pipeline} | ${r.culling} | ${ms} | ` +
            `${Math.round(r.meshlets_drawn)} | ${r.triangles_per_frame} | ${r.vertex_refs_per_frame ?? '-'} | ` +
            `${Math.round(j.meshlets_visible_oracle)} | ${Math.round(j.meshlets_unhidden_pose_box)} | ` +
            `${Math.round(j.meshlets_unhidden_pose_triangles)} | ` +
            `${r.draws_issued} | ${r.image_equal_to_unculled ? 'equal' : 'DIFFERENT'} |`);
    }
}
console.log(`\nadapter: ${adapter}${/llvmpipe|lavapipe/i.test(adapter) ? ' (lavapipe: the CPU\'s times, not a GPU\'s)' : ''}`);
EOF
