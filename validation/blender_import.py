#!/usr/bin/env python3
"""Blender as a client of icefem's USD export, headless through the ``bpy`` wheel.

    blender_import.py [--icefem target/release/icefem] [--keep DIR]

Runs two scenes with the built icefem and exports each to USD (``--fps 30``):

- the paper's scene with fracture to 30 s (a frame every 1/3 s: time codes 10 apart; the
  container as an obstacle; cracks from 21.7 s, so the topology changes);
- the gallery's thrown cube and turning paddle to 0.3 s (a mesh obstacle turning once a
  second over a floor plane).

Each stage is opened with ``python/blender/icefem_blender.py`` and checked:

- the scene's frame rate is the stage's ``framesPerSecond`` and its frame range the stage's
  time codes (first and last exported frame);
- the objects ``Ice``, ``Cracks`` and ``Obstacles`` are there with their materials (the ice's
  index of refraction 1.31);
- at three frames, each object's evaluated mesh has the points and triangles of the stage's
  sample at that time code (read from the ``.usda`` text independently of Blender; a still
  container's one value), with the same coordinates to f32 precision — which is where the
  paddle is at that time;
- a Cycles render of the last frame (160 × 120, 8 samples) shows the ice: at least 20 of its
  pixels differ from a render with the ice hidden.

Exits non-zero on any failure. Needs ``bpy`` 4.5 (Python 3.11):
``python3 -m venv target/blender-venv && target/blender-venv/bin/pip install bpy==4.5.3``.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python", "blender"))
import icefem_blender  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FAILED = []


def check(cond, message):
    if not cond:
        FAILED.append(message)
        print("FAIL:", message, file=sys.stderr)
    return cond


NUMBER = r"[-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?"


def usd_values(text, prim, attribute, code):
    """The numbers of ``prim``'s ``attribute`` at time code ``code`` in USDA text: its sample
    there, or its value where it is written once (obstacles that do not move)."""
    start = text.index(f'def Mesh "{prim}"')
    end = text.find("def Mesh", start + 1)
    block = text[start : end if end > 0 else len(text)]
    constant = re.search(rf"^ *{re.escape(attribute)} = \[(.*)\]$", block, re.M)
    if constant:
        return [float(x) for x in re.findall(NUMBER, constant.group(1))]
    at = block.index(f"{attribute}.timeSamples = {{\n")
    for line in block[at:].splitlines()[1:]:
        if line.strip() == "}":
            break
        sample, rest = line.strip().split(": [", 1)
        if float(sample) == code:
            return [float(x) for x in re.findall(NUMBER, rest)]
    raise KeyError(f"{prim} {attribute} has no sample at {code}")


def sample_codes(text):
    """The time codes of the ice's samples in USDA text."""
    start = text.index('def Mesh "Ice"')
    at = text.index("point3f[] points.timeSamples = {\n", start)
    codes = []
    for line in text[at:].splitlines()[1:]:
        if line.strip() == "}":
            break
        codes.append(float(line.strip().split(":", 1)[0]))
    return codes


def evaluated(ob):
    """(world-space vertex coordinates flattened, triangle count) of ``ob`` at the current
    frame, after its modifiers (the importer's mesh sequence cache)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    e = ob.evaluated_get(depsgraph)
    mesh = e.to_mesh()
    coords = [c for v in mesh.vertices for c in (e.matrix_world @ v.co)]
    triangles = sum(len(p.vertices) - 2 for p in mesh.polygons)
    e.to_mesh_clear()
    return coords, triangles


def check_stage(usda, png):
    text = open(usda, encoding="utf-8").read()
    fps, start, end = icefem_blender.stage_timing(usda)
    scene = icefem_blender.load(usda, samples=8)
    name = os.path.basename(usda)
    check(scene.render.fps / scene.render.fps_base == fps, f"{name}: scene at {scene.render.fps}/{scene.render.fps_base} fps, stage {fps}")
    check((scene.frame_start, scene.frame_end) == (int(start), int(end)), f"{name}: frames {scene.frame_start}–{scene.frame_end}, stage codes {start}–{end}")
    objects = {ob.name: ob for ob in scene.objects if ob.type == "MESH"}
    check(set(objects) == {"Ice", "Cracks", "Obstacles"}, f"{name}: objects {sorted(objects)}")
    ice_ior = objects["Ice"].material_slots[0].material.node_tree.nodes["Principled BSDF"].inputs["IOR"].default_value
    check(abs(ice_ior - 1.31) < 1e-6, f"{name}: ice IOR {ice_ior}")
    codes = sample_codes(text)
    compared = 0
    for code in [codes[0], codes[len(codes) // 2], codes[-1]]:
        scene.frame_set(int(code))
        for prim, ob in objects.items():
            points = usd_values(text, prim, "point3f[] points", code)
            counts = usd_values(text, prim, "int[] faceVertexCounts", code)
            coords, triangles = evaluated(ob)
            if not check(len(coords) == len(points) and triangles == len(counts), f"{name} {prim} @{code}: {len(coords) // 3} points, {triangles} triangles; stage {len(points) // 3}, {len(counts)}"):
                continue
            worst = max((abs(a - b) for a, b in zip(coords, points)), default=0.0)
            check(worst <= 1e-6 * max(1.0, max(map(abs, points), default=1.0)), f"{name} {prim} @{code}: coordinates off by {worst:.3g} m")
            compared += 1
    print(f"{name}: {fps:g} fps, frames {scene.frame_start}–{scene.frame_end}; {compared} object samples equal the stage's")

    # The ice shows: the render differs from one with the ice hidden (Cycles' noise is seeded,
    # so the two differ only where the ice is, or where it casts light and shadow).
    icefem_blender.render(scene, png, size=(160, 120))
    check(os.path.exists(png), f"{png} not written")
    objects["Ice"].hide_render = True
    without = png.replace(".png", "_without_ice.png")
    icefem_blender.render(scene, without, size=(160, 120))
    objects["Ice"].hide_render = False
    a, b = (list(bpy.data.images.load(f).pixels) for f in (png, without))
    differ = sum(max(abs(x - y) for x, y in zip(a[i : i + 3], b[i : i + 3])) > 0.05 for i in range(0, len(a), 4))
    check(differ >= 20, f"{png}: {differ} pixels show the ice")
    print(f"{png}: rendered, the ice on {differ} of {len(a) // 4} pixels")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--icefem", default=os.path.join(ROOT, "target", "release", "icefem"))
    ap.add_argument("--keep", metavar="DIR", help="write the runs, stages and renders here")
    a = ap.parse_args()
    work = a.keep or tempfile.mkdtemp(prefix="icefem_blender_")
    os.makedirs(work, exist_ok=True)
    runs = [
        ("paper", "scenes/freezing_container_fracture.toml", "30"),
        ("paddle", "scenes/gallery/thrown_cube_paddle.toml", "0.3"),
    ]
    for name, scene, end in runs:
        h5 = os.path.join(work, f"{name}.h5")
        subprocess.run([a.icefem, "-q", "run", os.path.join(ROOT, scene), "--end-time", end, "--output", h5, "--force"], check=True)
        subprocess.run([a.icefem, "-q", "export", h5, "--format", "usd", "--force", "--fps", "30"], check=True)
        check_stage(os.path.join(work, f"{name}.usda"), os.path.join(work, f"{name}.png"))
    print("all checks passed" if not FAILED else f"{len(FAILED)} checks failed")
    return 1 if FAILED else 0


if __name__ == "__main__":
    sys.exit(main())
