#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader (issue 21) with cargo-fuzz (libFuzzer, nightly Rust).
#
#   scripts/fuzz.sh [RUNS] [TARGET...]
#
# RUNS executions of each target (default 1,000,000; every target in fuzz/Cargo.toml when none
# is named). FUZZ_MAX_LEN caps an input's bytes (default 65536). Seeds come from the
# repository's own files (meshes converted to every format by `tissue mesh convert`, the
# shipped images, every scene, viewer messages, the small files in fuzz/seeds/), in
# fuzz/corpus/TARGET/ (not committed; libFuzzer adds what it finds there). A crashing input is
# copied to fuzz/regressions/TARGET/ (committed), which `cargo test` replays
# (crates/tissue/tests/fuzz_regressions.rs, and the viewer's in tissue-cli). A summary line per
# target goes to fuzz/last-run.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
runs=${1:-1000000}
shift || true

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked

targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(sed -n 's/^name = "\(.*\)"$/\1/p' fuzz/Cargo.toml | grep -v '^tissue-fuzz$')
fi

# Seeds: the shipped files in every format the readers take.
# TISSUE=path/to/tissue uses a binary already built.
if [ -z "${TISSUE:-}" ]; then
    cargo build --release --locked -p tissue-cli >/dev/null
fi
tissue=${TISSUE:-$root/target/release/tissue}
seeds=$(mktemp -d)
trap 'rm -rf "$seeds"' EXIT
for ext in stl msh vtk vtu vtp mesh off node; do
    "$tissue" mesh convert assets/meshes/liver.msh "$seeds/liver.$ext" >/dev/null
done
"$tissue" mesh convert assets/meshes/liver.obj "$seeds/liver-ascii.stl" --ascii >/dev/null
seed() {
    local target=$1; shift
    mkdir -p "fuzz/corpus/$target"
    for f in "$@"; do cp "$f" "fuzz/corpus/$target/"; done
}
for target in "${targets[@]}"; do
    case $target in
        mesh_obj) seed "$target" assets/meshes/liver.obj assets/meshes/liver-smooth.obj ;;
        mesh_stl) seed "$target" "$seeds/liver.stl" "$seeds/liver-ascii.stl" ;;
        mesh_ply) seed "$target" assets/meshes/wound_deformable.ply ;;
        mesh_msh) seed "$target" assets/meshes/liver.msh "$seeds/liver.msh" ;;
        mesh_vtk) seed "$target" "$seeds/liver.vtk" ;;
        # Small hand-checked files too (ascii and binary arrays): with FUZZ_MAX_LEN=4096 the
        # XML readers run several times faster and still see every kind of array.
        mesh_vtu) seed "$target" "$seeds/liver.vtu" fuzz/seeds/tet.vtu fuzz/seeds/tet-ascii.vtu ;;
        mesh_vtp) seed "$target" "$seeds/liver.vtp" fuzz/seeds/tet.vtp fuzz/seeds/tri-ascii.vtp ;;
        mesh_medit) seed "$target" "$seeds/liver.mesh" ;;
        mesh_off) seed "$target" "$seeds/liver.off" ;;
        mesh_tetgen)
            # node, ele and face in one input, split at 0xFF bytes.
            mkdir -p "fuzz/corpus/$target"
            { cat "$seeds/liver.node"; printf '\377'; cat "$seeds/liver.ele"; printf '\377'; cat "$seeds/liver.face" 2>/dev/null || true; } \
                >"fuzz/corpus/$target/liver" ;;
        image_nifti) seed "$target" assets/images/anatomical.nii ;;
        image_metaimage)
            mkdir -p "fuzz/corpus/$target"
            { sed 's/ElementDataFile = .*/ElementDataFile = data.raw/' assets/images/pelvis_f.mhd \
                | sed 's/DimSize = .*/DimSize = 4 4 2/'; printf '\377'; head -c 64 assets/images/pelvis_f.raw; } \
                >"fuzz/corpus/$target/pelvis-small" ;;
        image_nrrd)
            mkdir -p "fuzz/corpus/$target"
            printf 'NRRD0004\ntype: short\ndimension: 4\nspace: left-posterior-superior\nsizes: 2 2 2 1\nspace directions: none (-1.5,0,0) (0,2,0) (0,0,1)\nkinds: list domain domain domain\nendian: little\nencoding: raw\nspace origin: (1,2,3)\nspace units: "mm" "mm" "mm"\nSegment0_Name:=a\nSegment0_LabelValue:=1\nSegment0_Layer:=0\nSegment1_Name:=b\nSegment1_LabelValue:=1\nSegment1_Layer:=1\n\n\001\000\000\000\000\000\001\000\001\000\001\000\000\000\000\000' \
                >"fuzz/corpus/$target/layers"
            printf 'NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\ndata file: x.raw\nline skip: 1\n\377skip\n0 1 2 3 4 5 6 7\n' \
                >"fuzz/corpus/$target/detached" ;;
        scene_toml) seed "$target" scenes/*.toml ;;
        viewer_message)
            mkdir -p "fuzz/corpus/$target"
            i=0
            for m in '{"type":"probe","position":[0.0,0.05,0.0]}' '{"type":"probe","position":null}' \
                '{"type":"grasp","position":[0.01,0.04,0.0]}' '{"type":"release"}' \
                '{"type":"cut","path":[[0,0.05,0],[0.01,0.05,0]],"into":[0,-1,0]}' \
                '{"type":"set_model","kind":"fem-static"}' \
                '{"type":"set_material","young_modulus":3000.0,"poisson_ratio":0.3}' '{"type":"reset"}'; do
                printf '%s' "$m" >"fuzz/corpus/$target/m$i"; i=$((i + 1))
            done ;;
    esac
done

: >fuzz/last-run.txt
status=0
for target in "${targets[@]}"; do
    log=$(mktemp)
    echo "== $target: $runs runs"
    if (cd fuzz && cargo +nightly fuzz run "$target" "corpus/$target" -- \
        -runs="$runs" -max_len="${FUZZ_MAX_LEN:-65536}" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1) >"$log" 2>&1; then
        verdict=ok
    else
        verdict=CRASH
        status=1
        mkdir -p "fuzz/regressions/$target"
        cp fuzz/artifacts/"$target"/* "fuzz/regressions/$target/" 2>/dev/null || true
    fi
    done_line=$(grep -E '^Done [0-9]+ runs' "$log" | tail -1 || true)
    cov=$(grep -E 'stat::number_of_executed_units|cov: ' "$log" | tail -1 || true)
    echo "$target: $verdict; ${done_line:-no summary}; ${cov}" | tee -a fuzz/last-run.txt
    [ "$verdict" = ok ] || tail -40 "$log"
    rm -f "$log"
done
exit $status
