#!/bin/bash
# Runs a bundle from benchmarks/gpu_bundle.sh on a GPU machine: each GPU cut
# pass program's build time (filling the program cache, then copied to
# RESULTS_DIR/programs for a later call to carry), the GL tests, the cut
# pass's first use in two processes (its slow stages), and the render
# benchmark (bench_render --egl-device --frames 15, with the head when the
# bundle holds data/head.vdb), each under a time limit, writing
# RESULTS_DIR/{gpu_run.txt, bench_render.txt}. On an H100 the builds take
# 3.3 minutes, the cut-kernel tests up to 10 (CUT_TEST_S), the benchmark 4
# (BENCH_S): lower the limits to fit a lease. The GL tests that read
# ../shared/data find the bundle's data/ when MTCUT_DATA is not set.
#
# Usage: benchmarks/gpu_run.sh BUNDLE.tar.xz RESULTS_DIR
# Environment: BENCH_S (bench_render's limit, default 240), SHADER_S (each
# program's build, default 300), TEST_S (each test program, default 120),
# CUT_TEST_S (each of the two runs of test_render_cut_kernel, default 300),
# FIRST_USE_S (each of the two first-use runs of bench_render, default 90),
# BENCH_ARGS (extra bench_render arguments, e.g. --gpu-cut), MTCUT_SHADER_CACHE
# (the program cache's folder, default the bundle's programs/).
set -uo pipefail
if [ $# -ne 2 ]; then
    echo "usage: $0 BUNDLE.tar.xz RESULTS_DIR" >&2
    exit 2
fi
bundle=$(realpath "$1") results=$2
mkdir -p "$results" && results=$(realpath "$results")
exec > >(tee -a "$results/gpu_run.txt") 2>&1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
tar xJf "$bundle" -C "$dir" || exit 3
export LD_LIBRARY_PATH=$dir/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
ldconfig -p | grep -q 'libstdc++.so.6 ' || export LD_LIBRARY_PATH=$LD_LIBRARY_PATH:$dir/libfb
nvidia_json=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ] && [ -f "$nvidia_json" ]; then
    export __EGL_VENDOR_LIBRARY_FILENAMES=$nvidia_json
fi
export MTCUT_DATA=${MTCUT_DATA:-$dir/data}
cd "$dir" || exit 3
date
nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm --format=csv,noheader 2>&1
missing=$(ldd ./bench_render | grep "not found")
[ -n "$missing" ] && { echo "missing libraries:"; echo "$missing"; exit 4; }

export MTCUT_SHADER_CACHE=${MTCUT_SHADER_CACHE:-$dir/programs}
# NVIDIA's own shader cache too, in a folder of the run's and never pruned:
# it keeps what the driver does on a program's first use (45 s for the cut
# pass on an H200 with the programs from ours; 0.4 s in a later process).
export __GL_SHADER_DISK_CACHE=1 __GL_SHADER_DISK_CACHE_SKIP_CLEANUP=1
export __GL_SHADER_DISK_CACHE_PATH=${__GL_SHADER_DISK_CACHE_PATH:-$dir/nvcache}
mkdir -p "$__GL_SHADER_DISK_CACHE_PATH"

# The GPU cut pass's five programs first, side by side, each in a process of
# its own under SHADER_S ('-k': an NVIDIA 580 driver's compile did not end on
# TERM), into the program cache (render/Shaders.h, ProgramCache), from which
# the tests and the benchmark after take them in a fraction of a second (on
# the H100, 580.159.04: cut_arrange.vert built in 143 s, cut_regions.vert in
# 194 s; from the cache 133 and 89 ms). The error lines carry the driver's
# whole log less its warnings. The drawing passes' tests run meanwhile.
cut=(cut_phase_one.comp cut_vertex_positions.comp cut_names.comp cut_arrange.vert cut_regions.vert)
tmp=$(mktemp -d) pids=()
for p in "${cut[@]}"; do
    (timeout -k 5 "${SHADER_S:-300}" ./bench_render_shaders --egl-device --fill-cache "$p" > "$tmp/$p.txt" 2>&1
     echo "rc=$?" >> "$tmp/$p.txt") &
    pids+=($!)
done
tests() { # NAME...
    for t in "$@"; do
        echo "== $t"
        timeout -k 5 "${TEST_S:-120}" stdbuf -oL "./$t" --gtest_brief=1 2>&1 | tail -40
        echo "$t rc=${PIPESTATUS[0]} at ${SECONDS}s"
    done
}
tests test_render_gl test_render_mask test_render_frame test_render_kerf test_render_overlay test_render_timer test_render_poly2
wait "${pids[@]}" # these only: a bare wait would wait for the tee above
echo "== program build times"
for p in "${cut[@]}"; do
    rc=$(sed -n 's/^rc=//p' "$tmp/$p.txt")
    grep '^case=' "$tmp/$p.txt"
    [ "$rc" != 0 ] && echo "case=shader program=$p rc=$rc (124/137: not built within ${SHADER_S:-300} s)"
done
rm -rf "$tmp"
# The programs built here, for a later call on the same driver and GPU to
# carry and name in MTCUT_SHADER_CACHE (saves their 2-3 minutes of building).
[ "$MTCUT_SHADER_CACHE" = "$dir/programs" ] && cp -r "$MTCUT_SHADER_CACHE" "$results/programs" 2>/dev/null
echo "programs kept: $(ls "$results/programs" 2>/dev/null | wc -l) in $results/programs"
# The first cut of a process: the GPU cut pass's first draws took 28-58 s
# more than the next cut's with the programs from the cache. Twice, the
# second process after the first has filled NVIDIA's shader cache (above):
# whether that cache keeps the work; the stages it goes to
# (MTCUT_GPU_CUT_TIMES).
for run in 1 2; do
    echo "== first use, process $run: bench_render --gpu-cut --volumes 64x64x22 --targets 419 --frames 3"
    MTCUT_GPU_CUT_TIMES=1 timeout -k 5 "${FIRST_USE_S:-90}" ./bench_render --egl-device --gpu-cut --volumes 64x64x22 \
        --targets 419 --frames 3 2>&1 | grep -E '^gpu_cut|^case=gpucut|stage|rror' | cut -c1-300
    echo "first use $run rc=${PIPESTATUS[0]} at ${SECONDS}s"
done
# The cut pass against the CPU kernel: first the phases that name a
# difference most closely (phase one, positions from names, names: seconds),
# then the rest (the arrangement, the recovered geometry, the frames: minutes
# on the H100, hence CUT_TEST_S).
phases='CutKernelGpu.PhaseOne*:CutKernelGpu.VertexPositions*:CutKernelGpu.Names*'
for filter in "$phases" "-$phases"; do
    echo "== test_render_cut_kernel --gtest_filter=$filter"
    timeout -k 5 "${CUT_TEST_S:-300}" stdbuf -oL ./test_render_cut_kernel --gtest_brief=1 --gtest_filter="$filter" 2>&1 | tail -60
    echo "test_render_cut_kernel rc=${PIPESTATUS[0]} at ${SECONDS}s"
done

head=()
[ -f data/head.vdb ] && head=(--head data/head.vdb)
echo "== bench_render --egl-device --frames 15 ${head[*]} ${BENCH_ARGS:-}"
# shellcheck disable=SC2086
timeout -k 5 "${BENCH_S:-240}" ./bench_render --egl-device --frames 15 "${head[@]}" ${BENCH_ARGS:-} \
    > "$results/bench_render.txt" 2>&1
echo "bench_render rc=$? at ${SECONDS}s"
grep -v '^|' "$results/bench_render.txt" | cut -c1-300
echo "NVIDIA shader cache: $(du -sh "$__GL_SHADER_DISK_CACHE_PATH" 2>&1 | cut -f1)"
