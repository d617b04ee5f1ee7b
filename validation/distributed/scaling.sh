#!/usr/bin/env bash
# The scaling table of docs/distributed.md: the ice cubes of this folder (1e5 and 1e6 dofs,
# 3 backward-Euler steps) on one process with icefem's shared-memory multigrid (2 threads),
# on one process through PETSc (ICEFEM_DISTRIBUTE_ONE=1), on two processes through PETSc
# each holding its part of the mesh, and on two holding the whole mesh (ICEFEM_WHOLE_MESH=1,
# as scenes with ice–ice contact or fracture do). Prints, per run:
# seconds per Newton iteration (assembly, preconditioner set-up, solve), CG iterations per
# solve, peak memory (and the peak before the solvers' set-up: reading the scene, the
# partition, building the part) and nodes held per process, and the values each process
# exchanged per Newton iteration. Needs `make mpi` (binary with the `mpi` feature) and the
# validation venv (validation/setup_venv.sh) for h5py.
#   validation/distributed/scaling.sh [SIZES]     SIZES: 1e5 (default), 1e6, weak, setup
#   (weak: about 1e5 dofs per process, cube_1e5 on one process and cube_2e5 on two;
#    setup: the 1e5 and 1e6 cubes on 8 processes for one step, for the set-up's memory)
# ICEFEM_BIN and ICEFEM_PYTHON name another binary or Python.
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${ICEFEM_BIN:-target/release/icefem}
PY=${ICEFEM_PYTHON:-validation/.venv/bin/python}
MPIRUN="mpirun --oversubscribe --allow-run-as-root"
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
sizes=${*:-1e5}
summarise() { # label, h5, log
    "$PY" - "$1" "$2" "$3" <<'PY'
import sys, re, h5py, numpy as np
label, path, log = sys.argv[1:]
s = h5py.File(path)["stats"]
n = s["newton_iterations"][()].sum()
solves = s["factorizations"][()].sum()
per = lambda k: s[k][()].sum() / n
cg = s["linear_iterations"][()].sum() / n
text = open(log).read()
mem = re.findall(r"peak memory (\d+) MB \((\d+) MB", text)
maxrss = re.findall(r"maxrss (\d+)", text)
memory = "/".join(f"{p} ({u})" for p, u in mem) if mem else f"{int(maxrss[-1]) * 1024 // 10**6}"  # MB of 1e6 bytes, as icefem reports
traffic = re.findall(r"sums (\d+), matrix entries (\d+), gathered (\d+), CG halo (\d+)", text)
t = "; ".join("/".join(x) for x in traffic) if traffic else "-"
held = "/".join(re.findall(r"holds (\d+) nodes", text)) or "all"
print(f"| {label} | {n} | {per('t_assembly'):.3f} | {s['t_factorization'][()].sum():.2f} ({solves}) | "
      f"{per('t_solve'):.3f} | {cg:.0f} | {s['t_step'][()].sum():.1f} | {memory} | {held} | {t} |")
PY
}
echo "| run | Newton it. | assembly s/it | set-up s (count) | solve s/it | CG it./it | total s | peak MB per process (before the solvers' set-up) | nodes held per process | exchanged per it.: sums/entries/gathered/halo |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for size in $sizes; do
    if [ "$size" = setup ]; then
        # The set-up's memory per process where the part is small beside the whole mesh
        # every process reads: 8 processes, one step.
        for cube in 1e5 1e6; do
            $MPIRUN -n 8 "$BIN" run "validation/distributed/cube_$cube.toml" -o "$OUT/u.h5" --force --end-time 0.0334 2> "$OUT/u.log"
            summarise "$cube dofs, PETSc, 8 processes, parts, 1 step" "$OUT/u.h5" "$OUT/u.log"
        done
        continue
    fi
    if [ "$size" = weak ]; then
        # Weak scaling: about 1e5 dofs per process, the cube on one process and the cube
        # refined to twice the dofs on two, both through PETSc.
        ICEFEM_DISTRIBUTE_ONE=1 $MPIRUN -n 1 -x ICEFEM_DISTRIBUTE_ONE "$BIN" run validation/distributed/cube_1e5.toml -o "$OUT/k1.h5" --force 2> "$OUT/k1.log"
        summarise "1e5 dofs, PETSc, 1 process" "$OUT/k1.h5" "$OUT/k1.log"
        $MPIRUN -n 2 "$BIN" run validation/distributed/cube_2e5.toml -o "$OUT/k2.h5" --force 2> "$OUT/k2.log"
        summarise "2e5 dofs, PETSc, 2 processes, parts" "$OUT/k2.h5" "$OUT/k2.log"
        continue
    fi
    scene=validation/distributed/cube_$size.toml
    /usr/bin/time -f "maxrss %M" "$BIN" -q run "$scene" -o "$OUT/s.h5" --force 2> "$OUT/s.log"
    summarise "$size icefem AMG, 1 process" "$OUT/s.h5" "$OUT/s.log"
    ICEFEM_DISTRIBUTE_ONE=1 $MPIRUN -n 1 -x ICEFEM_DISTRIBUTE_ONE "$BIN" run "$scene" -o "$OUT/p1.h5" --force 2> "$OUT/p1.log"
    summarise "$size PETSc, 1 process" "$OUT/p1.h5" "$OUT/p1.log"
    $MPIRUN -n 2 "$BIN" run "$scene" -o "$OUT/p2.h5" --force 2> "$OUT/p2.log"
    summarise "$size PETSc, 2 processes, parts" "$OUT/p2.h5" "$OUT/p2.log"
    ICEFEM_WHOLE_MESH=1 $MPIRUN -n 2 -x ICEFEM_WHOLE_MESH "$BIN" run "$scene" -o "$OUT/w2.h5" --force 2> "$OUT/w2.log"
    summarise "$size PETSc, 2 processes, whole mesh" "$OUT/w2.h5" "$OUT/w2.log"
done
