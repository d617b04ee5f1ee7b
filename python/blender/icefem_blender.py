"""Open an icefem USD export in Blender, ready to play and render.

    blender --background --python icefem_blender.py -- RUN.usda [--render OUT.png] [--frame F]
    python icefem_blender.py RUN.usda [--blend OUT.blend] [--render OUT.png]   # the bpy wheel

or, inside Blender's Python console, ``icefem_blender.load("RUN.usda")``.

What it sets up (docs/output.md#blender):

- the stage's objects through Blender's USD importer: ``Ice``, ``Cracks`` and, where the run
  had them, ``Obstacles``, animated (the importer reads each time-varying mesh through a
  Mesh Sequence Cache modifier);
- the scene's frame rate from the stage's ``framesPerSecond`` (the ``--fps`` of
  ``icefem export``), its frame range from the stage's start and end time codes;
- materials: ice transmissive with index of refraction 1.31 (ice's, ordinary ray, visible
  light), the cracks their own (a light, rough, opaque surface so that they show inside the
  ice), obstacles as clear glass sheets — transmissive with index 1: an obstacle is one
  surface with no thickness, and an index above 1 would bend the light entering it with
  nothing to bend it back, so a container is seen through undistorted;
- a camera looking at the scene's box from above and to the side (azimuth 45°, elevation
  30°, 30° field of view, framed to the box at the first frame) and a sun above it; Cycles on
  the CPU, 32 samples with denoising off, so that a frame renders in seconds.
"""

import argparse
import math
import re
import sys

import bpy
from mathutils import Vector

#: Index of refraction of ice (ordinary ray, visible light).
ICE_IOR = 1.31
#: Index of refraction given to obstacles: 1, a sheet with no thickness bends no light.
SHEET_IOR = 1.0


def stage_timing(usda):
    """(framesPerSecond, startTimeCode, endTimeCode) of a USDA stage's header."""
    # The layer's metadata block precedes its first prim (a stage of many frames is large:
    # read no further).
    lines = []
    with open(usda, encoding="utf-8") as f:
        for line in f:
            if line.startswith("def "):
                break
            lines.append(line)
    head = "".join(lines)

    def number(key, default):
        m = re.search(rf"\b{key}\s*=\s*([-+0-9.eE]+)", head)
        return float(m.group(1)) if m else default

    return number("framesPerSecond", 24.0), number("startTimeCode", 0.0), number("endTimeCode", 0.0)


def principled(name, color, transmission=0.0, ior=1.45, roughness=0.5, alpha=1.0):
    """A Principled BSDF material."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Transmission Weight"].default_value = transmission
    bsdf.inputs["IOR"].default_value = ior
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Alpha"].default_value = alpha
    return m


def scene_box(objects):
    """The box around ``objects``' evaluated geometry at the current frame (world space)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lo = Vector((math.inf,) * 3)
    hi = Vector((-math.inf,) * 3)
    for ob in objects:
        evaluated = ob.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        for v in mesh.vertices:
            x = evaluated.matrix_world @ v.co
            lo = Vector(map(min, lo, x))
            hi = Vector(map(max, hi, x))
        evaluated.to_mesh_clear()
    return lo, hi


def load(usda, samples=32):
    """Replaces the open scene by the export ``usda``, with materials, camera, light and
    render settings; returns the scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    fps, start, end = stage_timing(usda)
    bpy.ops.wm.usd_import(filepath=usda, set_frame_range=True, import_cameras=False, import_lights=False)
    scene = bpy.context.scene
    # Blender's frame rate is fps / fps_base, fps an integer: 29.97 is 30 / 1.001.
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps
    scene.frame_start = int(math.floor(start))
    scene.frame_end = int(math.ceil(end))
    scene.frame_set(scene.frame_start)

    looks = {
        "Ice": principled("icefem ice", (0.85, 0.93, 1.0), transmission=1.0, ior=ICE_IOR, roughness=0.05),
        "Cracks": principled("icefem cracks", (0.95, 0.95, 0.97), roughness=0.8),
        "Obstacles": principled("icefem glass", (0.9, 0.95, 1.0), transmission=1.0, ior=SHEET_IOR, roughness=0.02),
    }
    meshes = [ob for ob in scene.objects if ob.type == "MESH"]
    for ob in meshes:
        material = next((m for name, m in looks.items() if ob.name.startswith(name)), None)
        if material is not None:
            # On the object, not its mesh: the cache modifier replaces the mesh every frame
            # where fracture changes the topology.
            if not ob.material_slots:
                ob.data.materials.append(None)
            for slot in ob.material_slots:
                slot.link = "OBJECT"
                slot.material = material

    lo, hi = scene_box(meshes)
    centre = (lo + hi) / 2
    radius = max((hi - lo).length / 2, 1e-3)
    fov = math.radians(30.0)
    azimuth, elevation = math.radians(45.0), math.radians(30.0)
    direction = Vector((math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)))
    camera_data = bpy.data.cameras.new("icefem camera")
    camera_data.sensor_fit = "VERTICAL"  # the field of view is the picture's height's
    camera_data.angle = fov
    camera_data.clip_start = radius * 1e-3
    camera_data.clip_end = radius * 1e3
    camera = bpy.data.objects.new("icefem camera", camera_data)
    scene.collection.objects.link(camera)
    camera.location = centre + direction * (1.1 * radius / math.sin(fov / 2))
    camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera

    sun_data = bpy.data.lights.new("icefem sun", type="SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("icefem sun", sun_data)
    scene.collection.objects.link(sun)
    sun.rotation_euler = (math.radians(35.0), 0.0, math.radians(20.0))
    world = bpy.data.worlds.new("icefem sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.62, 0.72, 1.0)
    scene.world = world

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    return scene


def render(scene, path, frame=None, size=(640, 480)):
    """Renders ``frame`` (default the last) of ``scene`` to the PNG ``path``."""
    scene.frame_set(scene.frame_end if frame is None else frame)
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def main(argv):
    ap = argparse.ArgumentParser(description="Open an icefem USD export in Blender")
    ap.add_argument("usda", help="the stage written by icefem export --format usd")
    ap.add_argument("--render", metavar="OUT.png", help="render a frame to this PNG")
    ap.add_argument("--frame", type=int, help="the frame to render (default: the last)")
    ap.add_argument("--size", default="640x480", help="render size WIDTHxHEIGHT (default 640x480)")
    ap.add_argument("--samples", type=int, default=32, help="Cycles samples (default 32)")
    ap.add_argument("--blend", metavar="OUT.blend", help="save the set-up scene")
    a = ap.parse_args(argv)
    scene = load(a.usda, samples=a.samples)
    fps = scene.render.fps / scene.render.fps_base
    objects = sorted(ob.name for ob in scene.objects if ob.type == "MESH")
    print(f"{a.usda}: {', '.join(objects)}; frames {scene.frame_start}–{scene.frame_end} at {fps:g} fps")
    if a.blend:
        bpy.ops.wm.save_as_mainfile(filepath=a.blend)
    if a.render:
        width, height = (int(v) for v in a.size.lower().split("x"))
        render(scene, a.render, a.frame, (width, height))
        print(f"rendered frame {scene.frame_current} to {a.render}")


if __name__ == "__main__":
    # Under `blender --python`, the script's arguments follow "--".
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
