#!/usr/bin/env bash
# Builds the libFuzzer targets in BUILD_DIR (default build/fuzz) with clang and
# runs each from its seed corpus, copied to a temporary folder so the
# repository is never written. Exits non-zero when a fuzzer finds a crash (the
# reproducer is left in BUILD_DIR/crashes/<target>/; add it to the corpus once
# mended).
#   FUZZ_SECONDS (default 20): how long each target runs, from a random seed:
#     exploration, by hand.
#   FUZZ_RUNS=N: N inputs per target from FUZZ_SEED (default 1) instead, the
#     same inputs on every machine: what the test command runs, so a red CI
#     is a regression, never a lucky find.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${1:-build/fuzz}"
seconds="${FUZZ_SECONDS:-20}"
if [ -n "${FUZZ_RUNS:-}" ]; then
  limit=(-runs="$FUZZ_RUNS" -seed="${FUZZ_SEED:-1}")
  what="$FUZZ_RUNS runs from seed ${FUZZ_SEED:-1}"
else
  limit=(-max_total_time="$seconds")
  what="${seconds} s"
fi
CC=clang CXX=clang++ cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j "${FUZZ_JOBS:-2}" >/dev/null
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
status=0
for target in metaimage rawoptions path; do
  cp -r "$here/corpus/$target" "$work/$target"
  mkdir -p "$build/crashes/$target"
  echo "fuzz_$target: $what, corpus of $(ls "$here/corpus/$target" | wc -l)"
  if ! "$build/fuzz_$target" "${limit[@]}" -print_final_stats=0 \
       -artifact_prefix="$build/crashes/$target/" "$work/$target" >"$work/$target.log" 2>&1; then
    echo "fuzz_$target: FAILED, see $build/crashes/$target/ and the log below" >&2
    tail -n 40 "$work/$target.log" >&2
    status=1
  else
    grep -E "^#[0-9]+.*(DONE|pulse)" "$work/$target.log" | tail -n 1 || true
  fi
done
exit $status
