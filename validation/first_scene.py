"""Runs docs/first_scene.md as written: its files, its commands, and checks its quoted output.

The page's fenced blocks are read in order:
  - ```python / ```toml blocks whose first line is `# file: NAME` are written to NAME;
  - ```sh blocks are run line by line with bash (each must succeed);
  - ```text blocks are output the previous command must have printed, line for line
    (each line must appear in its stderr or stdout).
Then the files the page says the commands write are checked to exist.

Run from anywhere (part of `make test`):
  target/gmsh-venv/bin/python validation/first_scene.py
It needs target/release/icefem (cargo build --release) and a Python with gmsh as `python3`:
the interpreter running this script goes first on PATH, so run it with the gmsh venv's.
Works in a temporary folder, removed at the end (kept with --keep FOLDER).
"""
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGE = os.path.join(ROOT, "docs", "first_scene.md")
WRITTEN = ["water.msh", "glass.msh", "glass_of_water.h5", "glass_of_water.xdmf",
           "glass_of_water.cracks.xdmf", "glass_of_water.png", "glass_of_water_cut.png",
           "glass_of_water.usda"]


def blocks(text):
    """(language, lines) of each fenced block, in order."""
    for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, flags=re.S | re.M):
        yield m.group(1), m.group(2).splitlines()


def main():
    keep = sys.argv[sys.argv.index("--keep") + 1] if "--keep" in sys.argv else None
    icefem = os.path.join(ROOT, "target", "release", "icefem")
    if not os.access(icefem, os.X_OK):
        sys.exit(f"error: {icefem} is missing: run cargo build --release first")
    env = dict(os.environ)
    # icefem and this Python (with gmsh, as `python3`) first on PATH, as a user's shell has them.
    python_bin = os.path.dirname(os.path.abspath(sys.executable))
    env["PATH"] = os.pathsep.join([os.path.dirname(icefem), python_bin, env.get("PATH", "")])
    work = keep or tempfile.mkdtemp(prefix="first_scene_")
    os.makedirs(work, exist_ok=True)
    with open(PAGE, encoding="utf-8") as f:
        page = f.read()
    last_output = ""
    commands = 0
    for language, lines in blocks(page):
        if language in ("python", "toml") and lines and lines[0].startswith("# file: "):
            name = lines[0][len("# file: "):].strip()
            with open(os.path.join(work, name), "w", encoding="utf-8") as f:
                f.write("\n".join(lines) + "\n")
        elif language == "sh":
            for command in lines:
                if not command.strip():
                    continue
                print(f"$ {command}", flush=True)
                run = subprocess.run(["bash", "-c", command], cwd=work, env=env,
                                     capture_output=True, text=True)
                last_output = run.stdout + run.stderr
                if run.returncode != 0:
                    sys.exit(f"error: `{command}` exited with {run.returncode}:\n{last_output}")
                commands += 1
        elif language == "text":
            missing = [line for line in lines if line.strip() and line not in last_output]
            if missing:
                sys.exit("error: the page quotes output the run did not print:\n  "
                         + "\n  ".join(missing) + f"\nthe run printed:\n{last_output}")
    absent = [name for name in WRITTEN if not os.path.exists(os.path.join(work, name))]
    if absent:
        sys.exit(f"error: the commands did not write {absent} in {work}")
    print(f"docs/first_scene.md: {commands} commands ran and printed what the page quotes")
    if not keep:
        subprocess.run(["rm", "-rf", work], check=True)


if __name__ == "__main__":
    main()
