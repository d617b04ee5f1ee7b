"""Render one frame of an `icefem export --format vtu` with pyvista (VTK), a tool that is not
icefem: the picture in the README that shows the export opens elsewhere.

    icefem run scenes/freezing_container_fracture.toml --output paper.h5
    icefem export paper.h5 --format vtu --frames 240:240        # → paper_export/
    python validation/render_export.py paper_export/paper --output docs/export_pyvista.png

Needs pyvista (pip install pyvista; it renders off screen, no display needed). The ice's outer
surface is drawn translucent and coloured by von Mises stress (its point attribute), the crack
surfaces opaque red.
"""
import argparse

import pyvista as pv


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("prefix", help="the export's files without _ice_NNNNNN.vtu, e.g. paper_export/paper")
    ap.add_argument("--frame", type=int, default=0, help="exported frame number (default 0)")
    ap.add_argument("--output", default="export_pyvista.png")
    a = ap.parse_args()
    ice = pv.read(f"{a.prefix}_ice_{a.frame:06d}.vtu")
    cracks = pv.read(f"{a.prefix}_cracks_{a.frame:06d}.vtu")
    plotter = pv.Plotter(off_screen=True, window_size=(800, 600))
    plotter.set_background("white")
    plotter.add_mesh(
        ice,
        scalars="von_mises",
        cmap="viridis",
        opacity=0.35,
        scalar_bar_args={"title": "von Mises stress (Pa)", "color": "black", "width": 0.6, "position_x": 0.2, "fmt": "%.3g"},
    )
    if cracks.n_cells:
        plotter.add_mesh(cracks, color="firebrick")
    plotter.add_text("icefem export (VTU), drawn by pyvista", font_size=10, color="black")
    plotter.camera_position = "iso"
    plotter.camera.zoom(1.2)
    plotter.screenshot(a.output)
    print(f"wrote {a.output}: {ice.n_points} ice points, {cracks.n_cells} crack triangles")


if __name__ == "__main__":
    main()
