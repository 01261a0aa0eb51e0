#!/usr/bin/env bash
# The README's two commands. Installs what is missing (Debian packages, as
# root), builds in Release, then either runs the main job on the built-in
# phantom (demo) or runs every test (test). Quiet when nothing is missing.
#
#   bash tools/setup.sh demo     install, build, run the main job
#   bash tools/setup.sh test     install, build, run all tests
#   bash tools/setup.sh deps     only install what is missing
#   bash tools/setup.sh build    install and build
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD=${MTCUT_BUILD_DIR:-$ROOT/build}
JOBS=${MTCUT_JOBS:-$(nproc)}

PACKAGES=(
  cmake ninja-build g++ pkg-config zlib1g-dev
  libopenvdb-dev libboost-iostreams-dev libtbb-dev
  libopenmesh-dev libopenexr-dev libimath-dev libglm-dev
  libgdcm-dev libnifti2-dev libteem-dev
  libglfw3-dev libepoxy-dev libegl-dev libgl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri libimgui-dev libpng-dev
  libgtest-dev libbenchmark-dev xvfb clang libclang-rt-14-dev
  libcgal-dev libgmp-dev libmpfr-dev
)

deps() {
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  ((${#missing[@]})) || return 0
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  echo "setup: installing ${missing[*]}"
  local start=$SECONDS
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  echo "setup: installed in $((SECONDS - start)) s"
}

build() {
  local start=$SECONDS
  if [ ! -f "$BUILD/CMakeCache.txt" ]; then
    cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  fi
  # Ninja's per-file progress lines are noise here; errors still show.
  local log
  log=$(mktemp)
  if ! cmake --build "$BUILD" -j "$JOBS" >"$log" 2>&1; then
    grep -vE '^\[[0-9]+/[0-9]+\] ' "$log" >&2 || true
    rm -f "$log"
    echo "setup: build failed" >&2
    exit 1
  fi
  grep -iE 'warning' "$log" >&2 || true
  rm -f "$log"
  echo "setup: built in $((SECONDS - start)) s"
}

demo() {
  local out="$BUILD/demo" mtcut="$BUILD/tools/mtcut"
  mkdir -p "$out"
  "$mtcut" phantom "$out/phantom.vdb"
  "$mtcut" info "$out/phantom.vdb"
  "$mtcut" mesh "$out/phantom.vdb" --iso 400 -o "$out/phantom_bone.stl" --check
  "$mtcut" cut "$out/phantom.vdb" --iso 400 --path "$ROOT/tools/phantom_lefort.csv" -o "$out/cut" --check
  echo "demo: files in $out (the cut fragments, cut.vdb, slices.exr and summary.json in $out/cut)"
}

run_tests() {
  # ctest, then the libFuzzer targets and the ThreadSanitizer hand-off test;
  # the last line sums them up ("N passed, N failed").
  # The test command must stay under 30 minutes on 2 cores: each part's
  # time is printed, so a slow part shows in the CI log.
  local log passed failed skipped extra_pass=0 extra_fail=0 status=0 start=$SECONDS
  log=$(mktemp)
  ctest --test-dir "$BUILD" --output-on-failure -j "$JOBS" --timeout 1200 | tee "$log" || status=1
  passed=$(sed -nE 's/.* tests passed, ([0-9]+) tests failed out of ([0-9]+).*/\2 \1/p' "$log" | awk '{print $1-$2}')
  failed=$(sed -nE 's/.* tests passed, ([0-9]+) tests failed out of ([0-9]+).*/\1/p' "$log")
  # ctest counts a skipped test (GTEST_SKIP: shared data or a tool not
  # found) as passed; it lists each as "(Skipped)".
  skipped=$(grep -c '(Skipped)$' "$log" || true)
  passed=$(( ${passed:-0} - skipped ))
  rm -f "$log"
  echo "tests: ctest took $((SECONDS - start)) s"
  start=$SECONDS
  if [ -f "$ROOT/tests/fuzz/run.sh" ]; then
    if FUZZ_RUNS="${FUZZ_RUNS:-200000}" bash "$ROOT/tests/fuzz/run.sh" "$BUILD/fuzz"; then extra_pass=$((extra_pass + 1)); else extra_fail=$((extra_fail + 1)); status=1; fi
  fi
  echo "tests: the fuzz targets took $((SECONDS - start)) s"
  start=$SECONDS
  if [ -f "$ROOT/tests/tsan/run.sh" ]; then
    if bash "$ROOT/tests/tsan/run.sh" "$BUILD/tsan"; then extra_pass=$((extra_pass + 1)); else extra_fail=$((extra_fail + 1)); status=1; fi
  fi
  echo "tests: the ThreadSanitizer test took $((SECONDS - start)) s"
  if [ "$skipped" -gt 0 ]; then
    echo "note: $skipped test(s) skipped (shared data not found: set MTCUT_DATA; or xvfb-run missing); see above"
  fi
  echo "tests: $(( passed + extra_pass )) passed, $(( ${failed:-1} + extra_fail )) failed, $skipped skipped"
  return $status
}

case "${1:-}" in
  deps) deps ;;
  build) deps; build ;;
  demo) deps; build; demo ;;
  test) deps; build; run_tests ;;
  *) echo "usage: bash tools/setup.sh demo|test|deps|build" >&2; exit 2 ;;
esac
