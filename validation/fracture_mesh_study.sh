#!/usr/bin/env bash
# The paper's scene with fracture on four meshes (216, 1 728, 10 368 and 24 576 tets) and the
# mesh-dependence measures between them (docs/validation.md, "The paper's scene with
# fracture"). The first three are the committed scenes; the fourth is
# freezing_container_fine.toml with cells = [16, 16, 16]. About 45 minutes on 2 cores
# (the 24 576-tet run alone ~33 min); pass --quick to skip it.
#
#   validation/fracture_mesh_study.sh [--quick] [OUTDIR]     (default OUTDIR: target/mesh_study)
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(dirname "$HERE")"
QUICK=0
if [ "${1:-}" = "--quick" ]; then QUICK=1; shift; fi
OUT="${1:-$ROOT/target/mesh_study}"
mkdir -p "$OUT"

"$HERE/setup_venv.sh" >/dev/null
PY="$HERE/.venv/bin/python"
(cd "$ROOT" && cargo build --release --quiet)
ICEFEM="$ROOT/target/release/icefem"

sed 's/cells = \[12, 12, 12\]/cells = [16, 16, 16]/' "$ROOT/scenes/freezing_container_fine.toml" \
    > "$OUT/freezing_container_16.toml"
grep -q 'cells = \[16, 16, 16\]' "$OUT/freezing_container_16.toml"

run() { # name scene
    echo "== $1: $2"
    # Progress goes to the run's log; its last line (the summary, or the error) is shown.
    if ! "$ICEFEM" run "$2" --output "$OUT/$1.h5" --force > "$OUT/$1.log" 2>&1; then
        tail -1 "$OUT/$1.log"
        exit 1
    fi
    tail -1 "$OUT/$1.log"
    "$PY" "$HERE/fracture_table.py" "$OUT/$1.h5"
}
run p216 "$ROOT/scenes/freezing_container_fracture.toml"
run p1728 "$ROOT/scenes/freezing_container_fracture_1728.toml"
run p10368 "$ROOT/scenes/freezing_container_fine.toml"
[ "$QUICK" = 1 ] || run p24576 "$OUT/freezing_container_16.toml"

compare() { echo "== $1 against $2"; "$PY" "$HERE/fracture_table.py" --compare "$OUT/$1.h5" "$OUT/$2.h5" | tail -8; }
compare p216 p1728
compare p1728 p10368
[ "$QUICK" = 1 ] || compare p10368 p24576
