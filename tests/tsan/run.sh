#!/usr/bin/env bash
# Builds and runs the hand-off test under ThreadSanitizer.
# Usage: bash tests/tsan/run.sh BUILD_DIR   (exit non-zero on a failure or any TSan report)
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
BUILD="${1:-$HERE/../../build/tsan}"
GEN=()
command -v ninja >/dev/null && GEN=(-G Ninja)
cmake -S "$HERE" -B "$BUILD" "${GEN[@]}" >/dev/null
cmake --build "$BUILD" -j "${JOBS:-2}" >/dev/null
TSAN_OPTIONS="halt_on_error=1 exitcode=66 ${TSAN_OPTIONS:-}" "$BUILD/tsan_handoff"
