#!/bin/bash
# The whole test suite, ROUNDS times in a row (default 10), each time with a second full
# suite running beside it: two fresh clones of this repository, each with its own target
# directory, `cargo test --release` in both at once. Prints one line per round and exits 1
# if any suite failed.
#
#   validation/suite_under_load.sh [ROUNDS] [WORKDIR]
set -u
rounds=${1:-10}
work=${2:-$(mktemp -d)}
repo=$(cd "$(dirname "$0")/.." && pwd)
rm -rf "$work/a" "$work/b"
git clone -q "$repo" "$work/a" && git clone -q "$repo" "$work/b" || exit 1
for d in a b; do (cd "$work/$d" && cargo test --release --no-run -q) || exit 1; done
failed=0
for i in $(seq 1 "$rounds"); do
  start=$(date +%s)
  ( (cd "$work/b" && cargo test --release > "$work/beside_$i.log" 2>&1); echo $? > "$work/beside_$i.rc" ) &
  (cd "$work/a" && cargo test --release > "$work/main_$i.log" 2>&1); main=$?
  wait
  beside=$(cat "$work/beside_$i.rc")
  echo "round $i: suite rc $main, beside rc $beside, $(( $(date +%s) - start )) s"
  [ "$main" = 0 ] && [ "$beside" = 0 ] || failed=1
done
exit $failed
