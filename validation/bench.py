#!/usr/bin/env python3
"""Orchestrator of `validation/bench` (run that script, not this one: it sets up the system
packages, the venv and the release build first).

Runs icefem (`icefem bench --single N --steps 3 --solver cholesky|cg`) and the peer
(`bench_peer.py --single N`: scikit-fem + scipy / CHOLMOD / pyamg) on the same meshes, every
run in a fresh process, and writes validation/bench.md. icefem's side of each run is the
binary's own benchmark (src/bench/); this script adds what only it can: the peer runs
interleaved with icefem's, the machine-load checks and retries, the companion `icefem run`
scenes, and the side-by-side report. The problem's size and data come from bench_peer.py.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_peer import CLAMP_Z, DT, GRAVITY, LAMBDA, MU, RHO, SIDE, cells_for

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PEER = HERE / "bench_peer.py"

STEPS = 3
# The numbers `icefem bench --single` prints, in order: SINGLE_FIELDS in src/bench/driver.rs
# (a test there checks that this list matches).
ICEFEM_FIELDS = [
    "tets", "dofs", "nnz", "nnz_L", "t_model", "t_pattern", "t_symbolic", "t_assembly_step",
    "t_factor_step", "t_solve_step", "t_step", "newton", "lin_it", "peak_rss",
    "t_first_setup", "t_first_solve", "first_it", "amg_levels", "amg_complexity", "setups",
]

# (approximate tets, label, plan). Medians of 3 up to ~1e5 tets, 1 run above.
SIZES = [
    (1_000, "", dict(repeats=3, chol=True, cg=True, peer=True, spsolve=True, cholmod=True)),
    (10_000, "", dict(repeats=3, chol=True, cg=True, peer=True, spsolve=True, cholmod=True)),
    (17_000, "≈1e4 dofs", dict(repeats=3, chol=True, cg=True, peer=True, spsolve=True, cholmod=True)),
    (100_000, "", dict(repeats=3, chol=True, cg=True, peer=True, spsolve=False, cholmod=True)),
    (200_000, "≈1e5 dofs", dict(repeats=1, chol=True, cg=True, peer=True, spsolve=False, cholmod=True)),
    (1_000_000, "", dict(repeats=1, chol=False, cg=True, peer=True, spsolve=False, cholmod=False)),
]
QUICK_SIZES = [
    (1_000, "", dict(repeats=3, chol=True, cg=True, peer=True, spsolve=True, cholmod=True)),
    (10_000, "", dict(repeats=1, chol=True, cg=True, peer=True, spsolve=True, cholmod=True)),
]
# Wall-time caps per process (s); a run that hits its cap is reported, not retried.
TIMEOUT = {"chol": 900, "cg": 1200, "peer": 1200}
PEER_MEM_PER_TET = 7.5e3  # bytes: skfem COO assembly + pyamg at 1e6 tets, with margin
BACKGROUND_LIMIT = 0.25  # cores used by other processes during a run before it counts as disturbed

LOG = []


def log(msg: str) -> None:
    line = f"[{time.strftime('%H:%M:%S')}] {msg}"
    print(line, flush=True)
    LOG.append(line)


# ---------------------------------------------------------------------------------------------
# Report header: the machine, the software, the icefem build
# ---------------------------------------------------------------------------------------------
def output_of(cmd: list[str], default: str = "unknown") -> str:
    """cmd's stdout, stripped, run from the repository root; default if it cannot run or fails."""
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    except OSError:
        return default
    return r.stdout.strip() if r.returncode == 0 else default


def header_facts(icefem: Path, cholmod_note: str) -> dict:
    """The report header's machine, software and icefem lines (taken before the runs);
    cholmod_note is what the set-up says about scikit-sparse, unless it cannot be imported."""
    import importlib.metadata

    if subprocess.run([sys.executable, "-c", "import sksparse.cholmod"], capture_output=True).returncode:
        cholmod_note = "scikit-sparse not importable: no CHOLMOD columns"

    with open("/proc/cpuinfo") as f:
        cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), "")
    with open("/proc/meminfo") as f:
        kb = next(int(line.split()[1]) for line in f if line.startswith("MemTotal"))
    os_release = {}
    with open("/etc/os-release") as f:
        for line in f:
            key, _, value = line.strip().partition("=")
            os_release[key] = value.strip('"')
    libblas = Path("/usr/lib/x86_64-linux-gnu/libblas.so.3")
    blas = str(libblas.resolve()) if libblas.parent.is_dir() else "unknown"  # as `readlink -f`
    versions = []
    for name in ["scikit-fem", "numpy", "scipy", "scikit-sparse", "pyamg"]:
        try:
            versions.append(f"{name} {importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            versions.append(f"{name} (missing)")
    commit = output_of(["git", "rev-parse", "--short", "HEAD"])
    status = output_of(["git", "status", "--porcelain", "--untracked-files=no"], default="")
    dirty = " ".join(line.split()[1] for line in status.splitlines() if line.split()[1:])
    return dict(
        machine=f"{cpu}, {len(os.sched_getaffinity(0))} cores, {kb / 1048576:.1f} GiB RAM; "
                f"{os_release.get('PRETTY_NAME', '')}, Linux {platform.release()}",
        software=f"Python {platform.python_version()}, {', '.join(versions)}; CHOLMOD from Debian "
                 f"SuiteSparse (libcholmod3), BLAS {blas}; {cholmod_note}; {output_of(['rustc', '--version'])}",
        icefem=f"{output_of([str(icefem), '--version'])}, git {commit}"
               + (f" with uncommitted changes in {dirty}" if dirty else "")
               + "; release build; rayon on all cores",
    )


# ---------------------------------------------------------------------------------------------
# Machine load: CPU used by other processes while a measurement runs
# ---------------------------------------------------------------------------------------------
CLK = os.sysconf("SC_CLK_TCK")
NCPU = os.cpu_count() or 1


def cpu_busy_seconds() -> float:
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    idle = v[3] + v[4]  # idle + iowait
    return (sum(v[:8]) - idle) / CLK


def background_cores(sample: float = 1.0) -> float:
    b0, t0 = cpu_busy_seconds(), time.monotonic()
    time.sleep(sample)
    return (cpu_busy_seconds() - b0) / (time.monotonic() - t0)


WAIT_BUDGET = [300.0]  # seconds of waiting for a quiet machine, over the whole run


def wait_quiet(max_wait: float) -> float:
    """Waits (up to max_wait s, and within WAIT_BUDGET) until other processes use < 0.15 cores."""
    max_wait = min(max_wait, WAIT_BUDGET[0])
    start = time.monotonic()
    load = background_cores()
    announced = False
    while load > 0.15 and time.monotonic() - start < max_wait:
        if not announced:
            log(f"  machine busy ({load:.2f} cores used by other processes), waiting up to {max_wait:.0f} s")
            announced = True
        time.sleep(4.0)
        load = background_cores()
    WAIT_BUDGET[0] = max(0.0, WAIT_BUDGET[0] - (time.monotonic() - start))
    return load


def mem_available() -> int:
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    return 0


def run_process(cmd: list[str], timeout: float, env: dict | None = None) -> dict:
    """Runs cmd; returns stdout, stderr, status, wall time, child CPU, background cores."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        b0 = cpu_busy_seconds()
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, cwd=ROOT,
                                env=None if env is None else {**os.environ, **env})
        timed_out = False
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() - t0 > timeout:
                proc.kill()  # our own child only
                pid, status, ru = os.wait4(proc.pid, 0)
                timed_out = True
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.monotonic() - t0
        busy = cpu_busy_seconds() - b0
        child_cpu = ru.ru_utime + ru.ru_stime
        out.seek(0)
        err.seek(0)
        return dict(
            stdout=out.read().decode(errors="replace"),
            stderr=err.read().decode(errors="replace"),
            code=proc.returncode,
            timed_out=timed_out,
            wall=wall,
            child_cpu=child_cpu,
            background=max(0.0, (busy - child_cpu) / wall) if wall > 0 else 0.0,
            maxrss=ru.ru_maxrss * 1024,
        )


def measured(cmd: list[str], timeout: float, parse, what: str, deadline: float,
             env: dict | None = None) -> dict:
    """Runs a measurement, retrying (after waiting for quiet) if other processes disturbed it."""
    best = None
    for attempt in range(3):
        wait_quiet(min(180.0, max(0.0, deadline - time.monotonic() - 60)))
        r = run_process(cmd, timeout, env)
        if r["timed_out"]:
            return dict(error=f"stopped after {timeout:.0f} s (wall-time cap)", wall=r["wall"])
        if r["code"] != 0:
            tail = (r["stderr"].strip().splitlines() or ["?"])[-1]
            return dict(error=f"failed (exit {r['code']}): {tail}", wall=r["wall"])
        try:
            row = parse(r["stdout"])
        except (ValueError, KeyError, OSError) as e:
            return dict(error=f"unexpected output: {e}", wall=r["wall"])
        row["_wall"] = r["wall"]
        row["_background"] = r["background"]
        row["_maxrss"] = r["maxrss"]
        if best is None or row["_background"] < best["_background"]:
            best = row
        if r["background"] <= BACKGROUND_LIMIT:
            break
        if r["wall"] > 60 or time.monotonic() + 2 * r["wall"] > deadline:
            break  # long runs are not repeated: the budget matters more
        log(f"  {what}: other processes used {r['background']:.2f} cores during the run; repeating")
    if best["_background"] > BACKGROUND_LIMIT:
        log(f"  {what}: kept a run disturbed by {best['_background']:.2f} background cores")
    return best


EXPONENT = {"chol": 2.0, "cg": 1.4, "peer": 1.3}  # wall-time growth with size, for estimates
LAST_WALL: dict[str, tuple[int, float]] = {}


def estimate(job: str, n: int) -> float:
    """Wall time (s) of one run of `job` at n tets, scaled from the previous size run."""
    if job not in LAST_WALL:
        return 0.0
    n0, w0 = LAST_WALL[job]
    return w0 * (n / n0) ** EXPONENT[job]


SOLVER = {"chol": "cholesky", "cg": "cg", "amg": "amg"}


def icefem_single(icefem: Path, n: int, job: str) -> list[str]:
    """`icefem bench --single`: one run of icefem's benchmark at ≈n tets with job's solver."""
    return [str(icefem), "bench", "--single", str(n), "--steps", str(STEPS), "--solver", SOLVER[job]]


def peer_single(python: str, n: int, *flags: str) -> list[str]:
    """`bench_peer.py --single`: one run of the peer at ≈n tets."""
    return [python, str(PEER), "--single", str(n), *flags]


def parse_icefem(text: str) -> dict:
    vals = [float(v) for v in text.split()]
    if len(vals) != len(ICEFEM_FIELDS):
        raise ValueError(f"icefem bench printed {len(vals)} numbers, expected {len(ICEFEM_FIELDS)}: {text!r}")
    return dict(zip(ICEFEM_FIELDS, vals))


# ---------------------------------------------------------------------------------------------
# Companion `icefem run` scenes: what `icefem bench` does not print
# ---------------------------------------------------------------------------------------------
def cube_scene(cells, *, model: str, gravity, analysis: str, dt: float, end_time: float,
               output_every: int | None = None, linear: str | None = None) -> str:
    """The bench cube (bench_peer.py's size, material and clamp) as an `icefem run` scene on
    cells = (nx, ny, nz) box cells of 6 tets each."""
    nx, ny, nz = cells
    g = ", ".join(repr(float(x)) for x in gravity)
    text = f"""\
[mesh]
box = {{ origin = [0.0, 0.0, 0.0], size = [{SIDE!r}, {SIDE!r}, {SIDE!r}], cells = [{nx}, {ny}, {nz}], tets_per_cell = 6 }}

[material]
density = {RHO!r}
lambda = {LAMBDA!r}
mu = {MU!r}
model = "{model}"

[physics]
gravity = [{g}]

[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, {CLAMP_Z!r}]

[time]
analysis = "{analysis}"
dt = {dt!r}
end_time = {end_time!r}
"""
    if output_every is not None:
        text += f"output_every = {output_every}\n"
    if linear is not None:
        text += f'\n[solver]\nlinear = "{linear}"\ncg_tolerance = 1e-10\n'
    return text


COMPANIONS = {
    # Static equilibrium under the bench's gravity; step 1 solves it (Newton), steps 2-11 start
    # at the converged state and stop at iteration 0 after exactly one full assembly (energy,
    # gradient, Hessian) at a deformed state: their t_assembly is one full assembly.
    "static": dict(gravity=GRAVITY, analysis="static", dt=1.0, end_time=11.0, linear="cholesky"),
    # No loads, at rest: every step is one full assembly at F = I and nothing else (used where
    # the static solve is too expensive, i.e. 1e6 tets).
    "rest": dict(gravity=(0.0, 0.0, 0.0), analysis="dynamic", dt=DT, end_time=10 * DT, linear="cg"),
    # The bench problem itself as a scene: factorisations per step from /stats.
    "dyn": dict(gravity=GRAVITY, analysis="dynamic", dt=DT, end_time=3 * DT, linear="cholesky"),
}


def companion(icefem: Path, kind: str, cells: int, workdir: Path, what: str, deadline: float) -> dict:
    import h5py
    import numpy as np

    scene = workdir / f"{kind}_{cells}.toml"
    h5 = workdir / f"{kind}_{cells}.h5"
    scene.write_text(cube_scene((cells, cells, cells), model="corotated", output_every=100000,
                                **COMPANIONS[kind]))

    def parse(_stdout: str) -> dict:
        with h5py.File(h5, "r") as f:
            st = {k: f["stats"][k][:] for k in f["stats"]}
        newton = st["newton_iterations"]
        out = dict(steps=len(newton))
        if kind in ("static", "rest"):
            rows = slice(1, None) if kind == "static" else slice(None)
            if len(newton[rows]) == 0 or np.any(newton[rows] != 0):
                raise ValueError(f"{kind} scene: expected Newton to stop at iteration 0, got {newton.tolist()}")
            out["t_full_assembly"] = float(np.median(st["t_assembly"][rows]))
        else:
            out["newton"] = float(np.median(newton))
            if "factorizations" in st:
                fac = st["factorizations"]
                out["factorizations"] = float(np.median(fac))
                out["factorizations_list"] = fac.tolist()
                per = st["t_factorization"][fac > 0] / fac[fac > 0]
                out["t_per_factorization"] = float(np.median(per)) if per.size else 0.0
        return out

    try:
        return measured([str(icefem), "run", str(scene), "--output", str(h5), "--force"], 900, parse, what, deadline)
    except (ValueError, KeyError, OSError) as e:
        return dict(error=str(e))
    finally:
        for f in (h5, h5.with_suffix(".xdmf"), scene):
            f.unlink(missing_ok=True)


def parse_peer(text: str) -> dict:
    row = json.loads(text.strip().splitlines()[-1])
    if "t_cholmod_factor" in row:
        row["cholmod_total"] = row["t_cholmod_analyse"] + row["t_cholmod_factor"] + row["t_cholmod_solve"]
    if "t_amg_setup" in row:
        row["amg_total"] = row["t_amg_setup"] + row["t_amg_solve"]
    return row


def derive_icefem(res: dict) -> None:
    """Per-operation icefem figures from the bench medians and the companion scenes."""
    ch, cg = res["chol"], res["cg"]
    st, rest, dyn = res.get("static", {}), res.get("rest", {}), res.get("dyn", {})
    if "t_full_assembly" in st:
        res["asm_full"], res["asm_how"] = st["t_full_assembly"], "deformed"
    elif "t_full_assembly" in rest:
        res["asm_full"], res["asm_how"] = rest["t_full_assembly"], "rest"
    if "t_step" in ch:
        fac = dyn.get("factorizations")
        if fac and fac > 0:
            ch["factorizations"] = fac
            ch["factor_one"] = ch["t_factor_step"] / fac
        else:  # no companion: assume one factorisation per Newton iteration
            ch["factorizations"] = None
            ch["factor_one"] = ch["t_factor_step"] / max(ch["newton"], 1.0)
        ch["solve_one"] = ch["t_solve_step"] / max(ch["lin_it"], 1.0)  # one triangular solve per linear it.
        ch["direct"] = ch["t_symbolic"] + ch["factor_one"] + ch["solve_one"]


def medians(rows: list[dict]) -> dict:
    if not rows:
        return {}
    out = {}
    for k in rows[0]:
        vals = [r[k] for r in rows if k in r and isinstance(r[k], (int, float))]
        if vals:
            out[k] = statistics.median_low(vals) if len(vals) % 2 == 0 else statistics.median(vals)
        else:
            out[k] = rows[0][k]  # lists etc.: from the first run
    out["_runs"] = len(rows)
    out["_background_max"] = max(r.get("_background", 0.0) for r in rows)
    return out


# ---------------------------------------------------------------------------------------------
# Mesh check: the peer's box mesh against a mesh written by icefem
# ---------------------------------------------------------------------------------------------
def verify_meshes(icefem: Path, python: str) -> list[str]:
    lines = []
    with tempfile.TemporaryDirectory() as d:
        for cells in [(3, 4, 5), (6, 6, 6)]:
            scene = Path(d) / "mesh_check.toml"
            scene.write_text(cube_scene(cells, model="linear", gravity=GRAVITY, analysis="static",
                                        dt=1.0, end_time=1.0))
            h5 = Path(d) / "mesh_check.h5"
            r = subprocess.run([str(icefem), "run", str(scene), "--output", str(h5), "--force"],
                               capture_output=True, text=True, cwd=d)
            if r.returncode != 0:
                lines.append(f"icefem run failed for cells {cells}: {r.stderr.strip()[-300:]}")
                continue
            r = subprocess.run([python, str(PEER), "--verify-mesh", str(h5),
                                "--cells", ",".join(map(str, cells))],
                               capture_output=True, text=True)
            lines.append((r.stdout + r.stderr).strip() + ("" if r.returncode == 0 else "  **MISMATCH**"))
    return lines


# ---------------------------------------------------------------------------------------------
# Formatting
# ---------------------------------------------------------------------------------------------
def s(x, digits=3) -> str:
    if x is None:
        return "–"
    if x == 0:
        return "0"
    if abs(x) >= 100:
        return f"{x:.0f}"
    return f"{x:.{digits}g}"


def mb(x) -> str:
    return "–" if not x else f"{x / 1e6:.0f}"


def sci(x) -> str:
    return "–" if x is None else f"{x:.3g}"


def write_report(path: Path, results: list, meta: dict) -> None:
    L = []
    L.append("# icefem vs scikit-fem / scipy / CHOLMOD / pyamg — side-by-side benchmark\n")
    L.append(f"- **Command**: `{meta['command']}` (from the repository root)")
    L.append(f"- **Date**: {meta['date']}; total run time {meta['elapsed'] / 60:.1f} min")
    L.append(f"- **Machine**: {meta['machine']}")
    L.append(f"- **Software**: {meta['software']}")
    L.append(f"- **icefem**: {meta['icefem']}")
    L.append(f"- **Load**: {meta['load']}")
    L.append("")
    L.append("Problem (both sides, identical mesh and data): corotated (icefem) / linear (peer) ice "
             "cube 0.1 m, `cells_for(N)` = round(cbrt(N/6)) cells per axis, 6 Kuhn tets per cell "
             "(icefem's `box_mesh`), λ = 8.64e10 Pa, μ = 3.70e10 Pa, ρ = 916 kg/m³, nodes with "
             "z ≤ 1e-9 clamped, gravity (3, 0, −9.81) m/s², backward Euler h = 1/30 s, 3 steps "
             "(icefem). The peer solves the first Newton system of icefem's first step, "
             "A = K + M/h² on the free dofs with b = f (icefem's corotated tangent at rest is the "
             "same K).")
    L.append("")
    for line in meta["mesh_check"]:
        L.append(f"- Mesh check (icefem `run` output vs the peer's generator): {line}")
    L.append("")
    L.append("## Results\n")
    L.append("Times in seconds, memory in MB (peak RSS of the process, VmHWM). icefem columns: "
             "Cholesky runs, except *CG step* and the CG memory. Medians over *runs* fresh "
             "processes.\n")
    hdr = ["tets", "free dofs", "runs",
           "icefem full assembly ⁽¹⁾", "icefem symbolic", "icefem factor ⁽²⁾", "icefem solve ⁽²⁾",
           "icefem step, Cholesky", "icefem step, CG (CG it./solve)", "icefem peak mem Chol / CG",
           "skfem assembly, 4-pt default / 1-pt ⁽³⁾", "scipy spsolve", "CHOLMOD analyse + factor + solve",
           "pyamg SA setup + solve (it.)", "peer peak mem",
           "assembly: skfem / icefem, 4-pt / 1-pt ⁽⁴⁾", "direct: CHOLMOD / icefem ⁽⁵⁾"]
    L.append("| " + " | ".join(hdr) + " |")
    L.append("|" + "---|" * len(hdr))
    for res in results:
        ch, cg, pe = res["chol"], res["cg"], res["peer"]
        tets = ch.get("tets") or cg.get("tets") or pe.get("tets")
        dofs = ch.get("dofs") or cg.get("dofs") or pe.get("dofs")
        label = f" ({res['label']})" if res["label"] else ""
        runs = "/".join(str(x.get("_runs", 0)) for x in (ch, cg, pe))
        c = []
        c.append(f"{int(tets) if tets else '~' + str(res['n'])}{label}")
        c.append(str(int(dofs)) if dofs else "–")
        c.append(runs)
        c.append(s(res.get("asm_full")) + (" (at rest)" if res.get("asm_how") == "rest" else ""))
        if "t_step" in ch:
            nf = ch.get("factorizations")
            c += [s(ch["t_symbolic"]),
                  s(ch["factor_one"]) + (f" (×{nf:.0f}/step)" if nf else " (÷ Newton it.)"),
                  s(ch["solve_one"]) + f" (×{ch['lin_it']:.0f}/step)", s(ch["t_step"])]
        else:
            c += [res["chol_why"]] + ["–"] * 3
        c.append(f"{s(cg['t_step'])} ({cg['lin_it'] / max(cg['newton'], 1):.0f})" if "t_step" in cg
                 else res["cg_why"])
        c.append(f"{mb(ch.get('peak_rss'))} / {mb(cg.get('peak_rss'))}")
        if "t_assembly" in pe:
            c.append(f"{s(pe['t_assembly'])} / {s(pe.get('t_assembly_q1'))}")
            c.append(s(pe["t_spsolve"]) if "t_spsolve" in pe else res["spsolve_why"])
            if "cholmod_total" in pe:
                p1 = res.get("peer1t", {})
                c.append(f"{s(pe['t_cholmod_analyse'])} + {s(pe['t_cholmod_factor'])} + "
                         f"{s(pe['t_cholmod_solve'])} = **{s(pe['cholmod_total'])}**"
                         + (f" (1 BLAS thread: {s(p1['cholmod_total'])})" if "cholmod_total" in p1 else ""))
            else:
                c.append(res["cholmod_why"])
            c.append(f"{s(pe['t_amg_setup'])} + {s(pe['t_amg_solve'])} = **{s(pe['amg_total'])}** "
                     f"({pe['amg_iterations']:.0f})" if "amg_total" in pe else "–")
            c.append(mb(pe.get("peak_rss")))
        else:
            c += [res["peer_why"]] + ["–"] * 4
        if "t_assembly" in pe and "asm_full" in res:
            af = res["asm_full"]
            c.append(f"**{pe['t_assembly'] / af:.0f}×** / **{pe['t_assembly_q1'] / af:.1f}×**"
                     if "t_assembly_q1" in pe else f"**{pe['t_assembly'] / af:.0f}×**")
        else:
            c.append("–")
        if "cholmod_total" in pe and "direct" in ch:
            p1 = res.get("peer1t", {})
            c.append(f"**{pe['cholmod_total'] / ch['direct']:.2f}**"
                     + (f" (1 thread: {p1['cholmod_total'] / ch['direct']:.2f})" if "cholmod_total" in p1 else ""))
        else:
            c.append("–")
        L.append("| " + " | ".join(c) + " |")
    L.append("")
    L.append("*runs*: fresh processes per size for icefem Cholesky / icefem CG / peer (medians over them; "
             "icefem's per-step figures are themselves medians over the 3 steps of a run).\n")
    L.append("1. **icefem full assembly** = one evaluation of the corotated elastic energy, "
             "gradient and Hessian (CSC values of the free system) plus the inertia / load terms, in "
             "parallel on all cores, at a deformed state — measured exactly, as `/stats/t_assembly` "
             "of an `icefem run` of the same cube in *static* analysis under the same gravity: step 1 "
             "solves for equilibrium, steps 2–11 start there and Newton stops at iteration 0 after "
             "exactly one full assembly (median of steps 2–11). *(at rest)*: where that static solve "
             "is too expensive (1e6 tets), the same from an unloaded cube at rest (F = I, where "
             "nalgebra's SVD converges at once; compare both columns of the companion table below "
             "at the sizes where both were measured). `icefem bench`'s own `t_assembly/step` (raw table) "
             "is not one assembly: with chord Newton a step of 2 iterations runs 1 full assembly, "
             "2 gradient-only evaluations and 2 energy-only line-search evaluations. The one-time "
             "pattern / slot map / colouring set-up is not included (`t_pattern`, raw table).")
    L.append("2. **icefem factor** = `t_factorization/step` ÷ factorisations per step (×k/step: k "
             "read from `/stats/factorizations` of an `icefem run` of the bench problem as a "
             "scene; chord Newton reuses the step's factorisation for the second iteration). "
             "**solve** = `t_solve/step` ÷ triangular solves per step. faer supernodal LLᵀ, "
             "sequential, ordering `auto`: AMD below 5000 free dofs, METIS nested dissection on "
             "the node graph above. Symbolic analysis (incl. the ordering) runs once per mesh.")
    L.append("3. **skfem assembly** = `Basis(mesh, ElementVectorH1(ElementTetP1()), intorder=…)` + "
             "`asm(linear_elasticity)` for K + consistent mass `asm` row-summed to the lumped M + "
             "body-force `asm`, timed twice in the same process: with scikit-fem's default "
             "quadrature (4 points per tet) and with the 1-point rule (`intorder=1`), which is exact "
             "here (constant strains; linear integrands for the lumped mass and the load — K and f "
             "agree to round-off, column *1-pt vs 4-pt* in the raw table). The solvers use the 1-pt "
             "system. scikit-fem has no reusable pattern, so each assembly includes its COO → CSR "
             "conversion; the mesh object and the condensation to free dofs are not included.")
    L.append("4. Peer (basis + K + M + f) ÷ icefem full assembly, for the default and the 1-point "
             "scikit-fem assembly. The element work differs: icefem evaluates the corotated model "
             "(SVD-based polar decomposition, energy, gradient and tangent per element) where "
             "scikit-fem assembles the linear bilinear form.")
    L.append("5. CHOLMOD (analyse + factor + solve of A) ÷ icefem (symbolic + one numeric "
             "factorisation + one solve, from the Cholesky run). Above 1: icefem is faster; below "
             "1: CHOLMOD is faster. CHOLMOD's supernodal factorisation calls the multithreaded OpenBLAS "
             "(2 threads here) while icefem factors sequentially (faer `Par::Seq`); *(1 thread)* is "
             "CHOLMOD in a separate process with `OPENBLAS_NUM_THREADS=1` (1-pt assembly + "
             "CHOLMOD only, same medians). icefem's pattern keeps structural zeros (note 6).")
    L.append("")
    L.append("Peer details: scipy `spsolve` is SuperLU (COLAMD), run only up to 2e4 dofs. CHOLMOD "
             "through scikit-sparse `analyze` (default ordering: AMD, METIS tried when the fill is "
             "high) / `cholesky_inplace` / solve, supernodal, BLAS as listed above. pyamg: "
             "`smoothed_aggregation_solver(A as 3×3 BSR, B = 6 rigid-body modes)` with pyamg's "
             "defaults, then `solve(accel='cg', tol=1e-10)` (‖r‖/‖b‖ from x₀ = 0, as icefem's CG). "
             "icefem CG is Jacobi-preconditioned, relative tolerance 1e-10, from zero each "
             "Newton iteration. Each peer process first runs the whole pipeline on a 2×2×2 mesh "
             "(imports, first-call overheads) untimed; its peak memory includes the Python "
             "interpreter and libraries (~90 MB).")
    L.append("")
    if meta["notes"]:
        L.append("Skipped or capped:\n")
        for n in meta["notes"]:
            L.append(f"- {n}")
        L.append("")
    # raw tables
    L.append("## Raw medians — icefem\n")
    L.append("| solver | tets | free dofs | nnz(K) | nnz(L) | t_model | t_pattern | t_symbolic | "
             "t_assembly/step | t_factorization/step | t_solve/step | t_step | Newton it./step | "
             "lin. it./step | peak RSS (MB) | runs | max background cores |")
    L.append("|" + "---|" * 17)
    for res in results:
        for name in ("chol", "cg"):
            r = res[name]
            if "t_step" not in r:
                continue
            L.append(f"| {'Cholesky' if name == 'chol' else 'CG'} | {r['tets']:.0f} | {r['dofs']:.0f} | "
                     f"{sci(r['nnz'])} | {sci(r['nnz_L']) if r['nnz_L'] else '–'} | {s(r['t_model'])} | "
                     f"{s(r['t_pattern'])} | {s(r['t_symbolic'])} | {s(r['t_assembly_step'])} | "
                     f"{s(r['t_factor_step'])} | {s(r['t_solve_step'])} | {s(r['t_step'])} | "
                     f"{r['newton']:.0f} | {r['lin_it']:.0f} | {mb(r['peak_rss'])} | {r['_runs']} | "
                     f"{r['_background_max']:.2f} |")
    L.append("")
    L.append("Companion `icefem run` scenes (note 1 and 2): one full assembly from the static scene "
             "(deformed) and/or the unloaded scene (at rest); factorisations and Newton iterations per "
             "step of the bench problem run as a scene, and the time per factorisation there.\n")
    L.append("| tets | full assembly, deformed (s) | full assembly, at rest (s) | factorisations per step "
             "(steps 1–3) | Newton it./step | t_factorization ÷ factorisations (s) | runs |")
    L.append("|" + "---|" * 7)
    for res in results:
        st, rest, dyn = res.get("static", {}), res.get("rest", {}), res.get("dyn", {})
        if not (st or rest or dyn):
            continue
        tets = res["chol"].get("tets") or res["cg"].get("tets") or res["n"]
        fl = dyn.get("factorizations_list")
        L.append(f"| {tets:.0f} | {s(st.get('t_full_assembly'))} | {s(rest.get('t_full_assembly'))} | "
                 f"{', '.join(f'{x:.0f}' for x in fl) if isinstance(fl, list) else '–'} | "
                 f"{s(dyn.get('newton'))} | {s(dyn.get('t_per_factorization'))} | "
                 f"{st.get('_runs', 0)} / {rest.get('_runs', 0)} / {dyn.get('_runs', 0)} |")
    L.append("")
    L.append("## Raw medians — peer\n")
    L.append("| tets | free dofs | nnz(A) ⁽⁶⁾ | nnz(L) CHOLMOD | mesh | basis | K | M + f | basis 1-pt | "
             "K 1-pt | M + f 1-pt | 1-pt vs 4-pt | condense | "
             "spsolve | CHOLMOD analyse | factor | solve | pyamg setup | solve | CG it. | levels | "
             "‖Ax−b‖/‖b‖ spsolve / CHOLMOD / pyamg | peak RSS (MB) | runs | max background cores |")
    L.append("|" + "---|" * 25)
    for res in results:
        r = res["peer"]
        if "t_assembly" not in r:
            continue
        g = lambda k: s(r.get(k)) if k in r else "–"  # noqa: E731
        resid = " / ".join(sci(r[k]) if k in r else "–" for k in ("res_spsolve", "res_cholmod", "res_amg"))
        L.append(f"| {r['tets']:.0f} | {r['dofs']:.0f} | {sci(r['nnz'])} | "
                 f"{sci(r['nnz_L_cholmod']) if 'nnz_L_cholmod' in r else '–'} | {g('t_mesh')} | "
                 f"{g('t_basis')} | {g('t_K')} | {g('t_Mf')} | {g('t_basis_q1')} | {g('t_K_q1')} | "
                 f"{g('t_Mf_q1')} | {sci(r.get('q1_vs_default'))} | {g('t_system')} | {g('t_spsolve')} | "
                 f"{g('t_cholmod_analyse')} | {g('t_cholmod_factor')} | {g('t_cholmod_solve')} | "
                 f"{g('t_amg_setup')} | {g('t_amg_solve')} | "
                 f"{r['amg_iterations']:.0f} | {r['amg_levels']:.0f} | {resid} | {mb(r['peak_rss'])} | "
                 f"{r['_runs']} | {r['_background_max']:.2f} |" if "amg_iterations" in r else
                 f"| {r['tets']:.0f} | {r['dofs']:.0f} | {sci(r['nnz'])} | – | {g('t_mesh')} | {g('t_basis')} | "
                 f"{g('t_K')} | {g('t_Mf')} | {g('t_basis_q1')} | {g('t_K_q1')} | {g('t_Mf_q1')} | "
                 f"{sci(r.get('q1_vs_default'))} | {g('t_system')} | – | – | – | – | – | – | – | – | – | "
                 f"{mb(r['peak_rss'])} | {r['_runs']} | {r['_background_max']:.2f} |")
    L.append("")
    one = [(res, res.get("peer1t", {})) for res in results if "cholmod_total" in res.get("peer1t", {})]
    if one:
        L.append("CHOLMOD with one BLAS thread (`OPENBLAS_NUM_THREADS=1`), analyse / factor / solve (s): "
                 + "; ".join(f"{r['tets']:.0f} tets: {s(r['t_cholmod_analyse'])} / {s(r['t_cholmod_factor'])} / "
                             f"{s(r['t_cholmod_solve'])} ({r['_runs']} runs)" for _, r in one) + ".\n")
    L.append("6. scikit-fem drops exact zeros from K (`eliminate_zeros`: some off-diagonal entries of "
             "the 3×3 node blocks vanish on this structured mesh); icefem's pattern keeps full 3×3 "
             "blocks, hence nnz(K) > nnz(A). Both store both triangles.")
    L.append("")
    append_run_log(L)
    path.write_text("\n".join(L) + "\n")



def append_run_log(L):
    """Appends this run's log, folded, to the report lines L."""
    L.append("<details><summary>Run log</summary>\n")
    L.append("```")
    L.extend(LOG)
    L.append("```")
    L.append("</details>")

# ---------------------------------------------------------------------------------------------
# `validation/bench --amg`: icefem's multigrid-preconditioned CG against pyamg, up to 1e6 dofs
# ---------------------------------------------------------------------------------------------
# (approximate tets, label, repeats, run icefem Cholesky too)
AMG_SIZES = [
    (1_000, "", 3, True),
    (10_000, "", 3, True),
    (100_000, "", 3, True),
    (1_000_000, "", 1, False),
    (2_000_000, "≈1e6 dofs", 1, False),
]
AMG_QUICK_SIZES = [(1_000, "", 1, True), (10_000, "", 1, True)]


def loglog_slope(points) -> float:
    """Least-squares slope of log y against log x (the exponent p of y ∝ x^p)."""
    import math

    pts = [(math.log(x), math.log(y)) for x, y in points if x and y and x > 0 and y > 0]
    if len(pts) < 2:
        return float("nan")
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx else float("nan")


def amg_main(a, icefem: Path, python: str, meta_extra: dict) -> int:
    start = time.monotonic()
    deadline = start + a.budget * 60 - 30
    notes: list[str] = []
    sizes = AMG_QUICK_SIZES if a.quick else AMG_SIZES
    results = []
    for n, label, repeats, chol in sizes:
        jobs = ["amg"] + (["chol"] if chol else []) + ["peer"]
        need = PEER_MEM_PER_TET * n
        if need > 0.8 * mem_available():
            jobs.remove("peer")
            notes.append(f"{n} tets, peer: skipped, needs ≈{need / 1e9:.0f} GB")
        rows: dict[str, list] = {j: [] for j in jobs}
        for rep in range(repeats):
            for job in jobs:
                log(f"{n} tets: {job} run {rep + 1}/{repeats}")
                if job == "peer":
                    cmd = peer_single(python, n, "--spsolve-max-dofs", "0", "--no-cholmod")
                    r = measured(cmd, TIMEOUT["peer"], parse_peer, f"peer {n}", deadline)
                else:
                    r = measured(icefem_single(icefem, n, job), TIMEOUT["cg" if job == "amg" else "chol"],
                                 parse_icefem, f"icefem {job} {n}", deadline)
                if "error" in r:
                    notes.append(f"{n} tets, {job}: {r['error']}")
                    log(f"  {r['error']}")
                    continue
                if job == "peer":
                    log(f"  pyamg {r['amg_total']:.3g} s ({r['amg_iterations']} it.), "
                        f"{r['peak_rss'] / 1e6:.0f} MB, background {r['_background']:.2f}")
                else:
                    log(f"  first system {r['t_first_setup']:.3g} + {r['t_first_solve']:.3g} s "
                        f"({r['first_it']:.0f} it.), step {r['t_step']:.3g} s, "
                        f"{r['peak_rss'] / 1e6:.0f} MB, background {r['_background']:.2f}")
                rows[job].append(r)
        results.append(dict(n=n, label=label, **{j: medians(rows[j]) for j in jobs}))
    L = ["# icefem multigrid-preconditioned CG vs pyamg — side-by-side benchmark\n"]
    L.append(f"- **Command**: `{a.command}` (from the repository root)")
    L.append(f"- **Date**: {dt.datetime.now().astimezone().strftime('%Y-%m-%d %H:%M %Z')}; "
             f"total run time {(time.monotonic() - start) / 60:.1f} min")
    for k in ("machine", "software", "icefem"):
        if k in meta_extra:
            L.append(f"- **{k.capitalize()}**: {meta_extra[k]}")
    L.append("")
    L.append("Problem: the ice cube of `validation/bench` (0.1 m, Kuhn box mesh, base clamped, gravity "
             "(3, 0, −9.81) m/s², corotated, backward Euler h = 1/30 s, 3 steps), identical mesh on both "
             "sides. **First system** = the first Newton system of step 1, A = K + M/h² at rest, b = f — "
             "the system the peer solves: icefem AMG = multigrid set-up + PCG to ‖r‖/‖b‖ ≤ 1e-10; "
             "pyamg = `smoothed_aggregation_solver(A as 3×3 BSR, B = rigid-body modes)` + "
             "`solve(accel='cg', tol=1e-10)`; icefem Cholesky = symbolic + numeric factorisation + "
             "solve. **Step** = one backward-Euler step (assembly, Newton, line search; median of the "
             "3 steps), the multigrid hierarchy of step 1 reused while CG's iterations stay within "
             "1.5× + 2 of the first solve's. Peak memory = VmHWM of the process (the peer's includes "
             "its scikit-fem assembly). Medians of the runs listed.\n")
    L.append("| tets | free dofs | runs (AMG/Chol/peer) | icefem AMG first system: set-up + solve (CG it.) | "
             "pyamg set-up + solve (CG it.) | pyamg / icefem | icefem Cholesky first system | "
             "icefem step AMG / Cholesky | AMG levels / operator complexity | peak MB icefem AMG / Chol / peer |")
    L.append("|" + "---|" * 10)
    for res in results:
        am, ch, pe = res.get("amg", {}), res.get("chol", {}), res.get("peer", {})
        dofs = am.get("dofs") or pe.get("dofs")
        tets = am.get("tets") or pe.get("tets")
        ice = am["t_first_setup"] + am["t_first_solve"] if "t_first_setup" in am else None
        peer = pe.get("amg_total")
        c = [f"{tets:.0f}" + (f" ({res['label']})" if res["label"] else ""), f"{dofs:.0f}" if dofs else "–",
             "/".join(str(x.get("_runs", 0)) for x in (am, ch, pe))]
        c.append(f"{s(am['t_first_setup'])} + {s(am['t_first_solve'])} = **{s(ice)}** ({am['first_it']:.0f})"
                 if ice is not None else "–")
        c.append(f"{s(pe['t_amg_setup'])} + {s(pe['t_amg_solve'])} = **{s(peer)}** ({pe['amg_iterations']:.0f})"
                 if peer is not None else "–")
        c.append(f"**{peer / ice:.2f}**" if peer and ice else "–")
        c.append(f"{s(ch['t_first_setup'] + ch['t_first_solve'])}" if "t_first_setup" in ch else "– (fill ≈ 7 GB)")
        c.append(f"{s(am.get('t_step'))} / {s(ch.get('t_step'))}")
        c.append(f"{am['amg_levels']:.0f} / {am['amg_complexity']:.2f}" if "amg_levels" in am else "–")
        c.append(f"{mb(am.get('peak_rss'))} / {mb(ch.get('peak_rss'))} / {mb(pe.get('peak_rss'))}")
        L.append("| " + " | ".join(c) + " |")
    L.append("")
    pts = lambda job, f: [(r[job]["dofs"], f(r[job])) for r in results if r.get(job, {}).get("dofs")]  # noqa: E731
    L.append("Scaling exponent p of time ∝ dofs^p (least-squares slope of log time against log free dofs, "
             "over the sizes above):\n")
    L.append(f"- icefem AMG backward-Euler step: **{loglog_slope(pts('amg', lambda r: r['t_step'])):.2f}**")
    L.append(f"- icefem AMG first system (set-up + solve): "
             f"**{loglog_slope(pts('amg', lambda r: r['t_first_setup'] + r['t_first_solve'])):.2f}**")
    L.append(f"- pyamg set-up + solve: **{loglog_slope(pts('peer', lambda r: r.get('amg_total', 0))):.2f}**")
    L.append(f"- icefem Cholesky step (up to 1e5 tets): "
             f"**{loglog_slope(pts('chol', lambda r: r['t_step'])):.2f}**")
    L.append("")
    L.append("Raw icefem medians (per step: medians over the 3 steps; set-ups: over the run):\n")
    L.append("| solver | tets | free dofs | nnz(K) | pattern (s) | assembly/step (s) | set-up/step (s) | "
             "solve/step (s) | step (s) | Newton it./step | CG it./step | set-ups | peak MB |")
    L.append("|" + "---|" * 13)
    for res in results:
        for job in ("amg", "chol"):
            r = res.get(job, {})
            if "t_step" not in r:
                continue
            L.append(f"| {'AMG-CG' if job == 'amg' else 'Cholesky'} | {r['tets']:.0f} | {r['dofs']:.0f} | "
                     f"{sci(r['nnz'])} | {s(r['t_pattern'])} | {s(r['t_assembly_step'])} | "
                     f"{s(r['t_factor_step'])} | {s(r['t_solve_step'])} | {s(r['t_step'])} | "
                     f"{r['newton']:.0f} | {r['lin_it']:.0f} | {r['setups']:.0f} | {mb(r['peak_rss'])} |")
    L.append("")
    if notes:
        L.append("Notes:\n")
        L.extend(f"- {x}" for x in notes)
        L.append("")
    append_run_log(L)
    out = Path(a.output if a.output != str(HERE / "bench.md") else HERE / "bench_amg.md")
    out.write_text("\n".join(L) + "\n")
    log(f"wrote {out}")
    return 0


# ---------------------------------------------------------------------------------------------
def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--icefem", default=str(ROOT / "target/release/icefem"))
    ap.add_argument("--output", default=str(HERE / "bench.md"))
    ap.add_argument("--budget", type=float, default=30.0, help="minutes (soft cap for the whole run)")
    ap.add_argument("--quick", action="store_true", help="1e3 and 1e4 tets only (smoke test)")
    ap.add_argument("--amg", action="store_true",
                    help="instead: icefem AMG-CG vs pyamg up to 1e6 dofs (writes validation/bench_amg.md)")
    ap.add_argument("--command", default="validation/bench")
    ap.add_argument("--cholmod-note", default="scikit-sparse (CHOLMOD) installed",
                    help="what the set-up found about scikit-sparse (report header)")
    a = ap.parse_args()
    start = time.monotonic()
    hard_end = start + a.budget * 60 - 30  # no run is started that is expected to end later
    deadline = hard_end  # retries of disturbed runs and waits for a quiet machine stop here
    icefem = Path(a.icefem)
    python = sys.executable
    notes: list[str] = []
    facts = header_facts(icefem, a.cholmod_note)
    if a.amg:
        return amg_main(a, icefem, python, facts)

    log("mesh check: icefem box_mesh vs the peer's generator")
    mesh_check = verify_meshes(icefem, python)
    for line in mesh_check:
        log("  " + line)
    if any("MISMATCH" in l or "failed" in l for l in mesh_check):
        log("mesh check failed — the comparison would not be like for like; stopping")
        return 1

    workdir = Path(tempfile.mkdtemp(prefix="icefem-bench-"))
    sizes = QUICK_SIZES if a.quick else SIZES
    results = []
    for n, label, plan in sizes:
        res = dict(n=n, label=label, chol={}, cg={}, peer={}, chol_why="–", cg_why="–",
                   peer_why="–", spsolve_why="–", cholmod_why="–")
        results.append(res)
        cells = cells_for(n)
        # The jobs of a size run in rounds (icefem Cholesky, icefem CG, companion scene, peer),
        # so that slow phases of the (shared, virtualised) machine hit both sides alike.
        jobs = []
        for name in ("chol", "cg"):
            if plan[name]:
                jobs.append(name)
            else:
                res[f"{name}_why"] = ("skipped: nnz(L) ≈ 9e8 (≈ 7 GB) even with nested dissection, "
                                      "est. ≈ 3 min per factorisation, > 10 min per run")
        jobs += (["static"] if plan["chol"] else []) + ["rest"]
        if not plan["spsolve"]:
            res["spsolve_why"] = "skipped (> 2e4 dofs: SuperLU fill, minutes to hours)"
        if not plan["cholmod"]:
            res["cholmod_why"] = "skipped (CHOLMOD fill at 5e5 dofs: several GB and minutes)"
        need = PEER_MEM_PER_TET * n
        if need > 0.8 * mem_available():
            res["peer_why"] = f"skipped: needs ≈{need / 1e9:.0f} GB, {mem_available() / 1e9:.0f} GB available"
            notes.append(f"{n} tets, peer: {res['peer_why']}")
        else:
            jobs.append("peer")
            if plan["cholmod"]:
                jobs.append("peer1t")  # CHOLMOD with one BLAS thread (icefem factors sequentially)
        rows: dict[str, list] = {j: [] for j in jobs}
        failed: set[str] = set()
        for rep in range(plan["repeats"]):
            for job in jobs:
                if job in failed:
                    continue
                est = estimate(job, n) if job in EXPONENT else 0.0
                if time.monotonic() + est > hard_end:
                    notes.append(f"{n} tets, {job}: run {rep + 1} skipped: estimated {est / 60:.1f} min "
                                 f"does not fit the {a.budget:.0f}-min budget")
                    if not rows[job] and job in ("chol", "cg", "peer"):
                        res[f"{job}_why"] = "skipped (time budget)"
                    failed.add(job)
                    continue
                log(f"{n} tets: {job} run {rep + 1}/{plan['repeats']}")
                if job in ("chol", "cg"):
                    r = measured(icefem_single(icefem, n, job), TIMEOUT[job], parse_icefem,
                                 f"icefem {job} {n}", deadline)
                    if "error" not in r:
                        log(f"  {r['_wall']:.1f} s wall: step {r['t_step']:.4g} s, assembly/step "
                            f"{r['t_assembly_step']:.3g} s, {r['lin_it']:.0f} lin. it., "
                            f"{r['peak_rss'] / 1e6:.0f} MB, background {r['_background']:.2f}")
                elif job == "peer":
                    cmd = peer_single(python, n, "--spsolve-max-dofs", "20000" if plan["spsolve"] else "0",
                                      *([] if plan["cholmod"] else ["--no-cholmod"]))
                    r = measured(cmd, TIMEOUT["peer"], parse_peer, f"peer {n}", deadline)
                    if "error" not in r:
                        if "cholmod_error" in r:
                            res["cholmod_why"] = "scikit-sparse not importable"
                        log(f"  {r['_wall']:.1f} s wall: assembly {r['t_assembly']:.3g} s (1-pt {r['t_assembly_q1']:.3g} s)"
                            + (f", CHOLMOD {r['cholmod_total']:.3g} s" if "cholmod_total" in r else "")
                            + (f", pyamg {r['amg_total']:.3g} s ({r['amg_iterations']} it.)" if "amg_total" in r else "")
                            + f", {r['peak_rss'] / 1e6:.0f} MB, background {r['_background']:.2f}")
                elif job == "peer1t":
                    r = measured(peer_single(python, n, "--cholmod-only"), TIMEOUT["peer"], parse_peer, f"peer CHOLMOD 1 thread {n}", deadline,
                                 env={"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
                    if "error" not in r:
                        log(f"  CHOLMOD, 1 BLAS thread: {r.get('cholmod_total', float('nan')):.3g} s, "
                            f"background {r['_background']:.2f}")
                else:
                    r = companion(icefem, job, cells, workdir, f"icefem run {job} {n}", deadline)
                    if "error" not in r:
                        log(f"  full assembly {r['t_full_assembly']:.4g} s, background {r['_background']:.2f}")
                if "error" in r:
                    why = f"{'peer' if job == 'peer' else 'icefem'} {r['error']}"
                    if job in ("chol", "cg", "peer"):
                        res[f"{job}_why"] = why
                    notes.append(f"{n} tets, {job}: {r['error']}")
                    log(f"  {r['error']}")
                    failed.add(job)
                    continue
                rows[job].append(r)
                if job in EXPONENT:
                    LAST_WALL[job] = (n, r["_wall"])
                if rep == 0 and plan["repeats"] > 1 and r["_wall"] > 120:
                    notes.append(f"{n} tets, {job}: 1 run only ({r['_wall']:.0f} s per run)")
                    failed.add(job)
        for job in jobs:
            res[job] = medians(rows[job])
        if plan["chol"] and time.monotonic() < hard_end:
            log(f"{n} tets: dyn scene (factorisations per step)")
            r = companion(icefem, "dyn", cells, workdir, f"icefem run dyn {n}", deadline)
            if "error" in r:
                notes.append(f"{n} tets, dyn scene: {r['error']}")
                log(f"  {r['error']}")
            else:
                log(f"  factorisations per step {r.get('factorizations_list')}, Newton {r['newton']:.0f}, "
                    f"{r.get('t_per_factorization', 0):.4g} s per factorisation")
                res["dyn"] = medians([r])
        derive_icefem(res)

    shutil.rmtree(workdir, ignore_errors=True)
    elapsed = time.monotonic() - start
    meta = dict(facts)
    meta.update(
        command=a.command,
        date=dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        elapsed=elapsed,
        mesh_check=mesh_check,
        notes=notes,
    )
    bg = max([r[k].get("_background_max", 0.0) for r in results for k in ("chol", "cg", "peer")] or [0.0])
    meta["load"] = (f"each run starts once other processes use < 0.15 cores (waits up to 3 min, 5 min in "
                    f"all; {300 - WAIT_BUDGET[0]:.0f} s waited) and is "
                    f"repeated (up to twice) if they used > {BACKGROUND_LIMIT} cores during it; largest "
                    f"background load in a kept run: {bg:.2f} cores")
    write_report(Path(a.output), results, meta)
    log(f"wrote {a.output} ({elapsed / 60:.1f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
