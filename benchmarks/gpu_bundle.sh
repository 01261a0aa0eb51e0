#!/bin/bash
# Bundles the GL benchmarks and tests of a build, with the shared libraries
# they load, into one .tar.xz for a GPU machine that has an NVIDIA driver but
# not Debian's OpenVDB, TBB, OpenEXR, GDCM, ... packages. Left out: glibc
# and the GL loaders (libEGL, libOpenGL, libGLdispatch, ...), which must come
# from that machine (its driver, or Debian's glvnd packages unpacked there);
# libstdc++ and libgcc_s go in libfb/, used only where the machine has none.
#
# Usage: benchmarks/gpu_bundle.sh BUILD_DIR OUT.tar.xz [DATA_FILE ...]
#   DATA_FILE: copied into data/ (e.g. the VHM head as a .vdb written by
#   `mtcut convert ../shared/data/vhm-head-dicom head.vdb`: 26 MB against the
#   series' 102 MB; and the small volumes the GL tests read).
# Then on the GPU machine: benchmarks/gpu_run.sh OUT.tar.xz RESULTS_DIR.
set -euo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 BUILD_DIR OUT.tar.xz [DATA_FILE ...]" >&2
    exit 2
fi
build=$1 out=$2
shift 2
bins=(benchmarks/bench_render benchmarks/bench_render_shaders tests/test_render_gl tests/test_render_mask
      tests/test_render_frame tests/test_render_kerf tests/test_render_overlay tests/test_render_timer
      tests/test_render_poly2 tests/test_render_cut_kernel)
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/lib" "$stage/libfb" "$stage/data"
for b in "${bins[@]}"; do
    [ -x "$build/$b" ] || { echo "$0: $build/$b not built" >&2; exit 1; }
    cp "$build/$b" "$stage/"
    ldd "$build/$b" | awk '$3 ~ /^\// {print $3}'
done | sort -u | while read -r lib; do
    case $(basename "$lib") in
    libc.so* | libm.so* | libpthread* | libdl.so* | librt.so* | ld-linux* | libGL* | libEGL* | libOpenGL* | libGLX*) ;;
    libstdc++* | libgcc_s*) cp -L "$lib" "$stage/libfb/" ;;
    *) cp -L "$lib" "$stage/lib/" ;;
    esac
done
for f in "$@"; do cp "$f" "$stage/data/"; done
tar cf - -C "$stage" . | xz -T0 -6 > "$out.tmp"
mv "$out.tmp" "$out"
echo "$out: $(du -h "$out" | cut -f1) ($(ls "$stage/lib" | wc -l) libraries, ${#bins[@]} programs, $# data files)"
