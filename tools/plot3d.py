#!/usr/bin/env python3
"""A picture of a 3D run (issue 38, docs/3d.md "Pictures of a 3D run"): pyvista, off screen.

    python3 tools/plot3d.py RUN_FOLDER [--stage K] [--warp W] [--out PNG]

Reads the run folder's snapshot of a stage (`snapshot_NNNN_stageK.vtu`, the last one by
default) and its crack faces (`cracks_NNNN_stageK.vtu`, written by `flem run` once faces have
separated) and draws two views side by side:

- left: the body cut in half by a plane across its thinnest direction (`--no-cut`: the whole
  surface), displaced by the displacement times W (default: 5 % of the body's size over the
  largest displacement), coloured by the largest principal stress; its points are the
  clusters, so an open crack shows as a gap on the surface and on the cut;
- right: the crack faces alone inside the body's outline (reference shape): one side of each
  face separated at all its corners coloured by its opening (`opening`, the mean normal gap of
  the face's two sides), faces separated at some corners only faint grey; seen across the crack
  (along the least-spread direction of its faces' centres), tilted by 20 degrees.

Needs pyvista (0.49; VTK's OSMesa/EGL off-screen rendering: no X server). The picture is a view,
not a verification: tests/brazilian3.rs checks the crack's place.
"""
import argparse
import glob
import os
import re
import sys

import numpy as np
import pyvista as pv


def stage_files(folder, stage):
    snaps = sorted(glob.glob(os.path.join(folder, "snapshot_*_stage*.vtu")))
    if not snaps:
        sys.exit("error: %s holds no snapshot_*_stage*.vtu (is it the folder of a 3D `flem run`?)" % folder)
    if stage is not None:
        snaps = [s for s in snaps if re.search(r"_stage%d\.vtu$" % stage, s)]
        if not snaps:
            sys.exit("error: %s has no snapshot of stage %d" % (folder, stage))
    snap = snaps[-1]
    cracks = snap.replace("snapshot_", "cracks_")
    return snap, cracks if os.path.exists(cracks) else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder")
    ap.add_argument("--stage", type=int, default=None)
    ap.add_argument("--warp", type=float, default=None, help="displacement scale (default: 5 %% of the body's size)")
    ap.add_argument("--out", default=None, help="PNG (default: FOLDER/3d_view.png)")
    ap.add_argument("--title", default=None)
    ap.add_argument("--no-cut", dest="cut", action="store_false", help="the whole surface on the left, not the body cut in half")
    a = ap.parse_args()
    snap, cracks = stage_files(a.folder, a.stage)
    body = pv.read(snap)
    size = float(np.linalg.norm(np.ptp(body.points, axis=0)))
    umax = float(np.abs(body.point_data["displacement"]).max()) or 1.0
    warp = a.warp if a.warp is not None else 0.05 * size / umax
    out = a.out or os.path.join(a.folder, "3d_view.png")

    pv.OFF_SCREEN = True
    p = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1600, 760), border=False)
    p.set_background("white")
    ext = np.ptp(body.points, axis=0)
    c = np.asarray(body.center)
    thin = int(np.argmin(ext))
    # The warped body cut in half across its thinnest direction (the plane cut shows the crack inside;
    # --no-cut: the whole surface).
    warped = body.warp_by_vector("displacement", factor=warp)
    if a.cut:
        warped = warped.clip(normal=tuple(np.eye(3)[thin]), origin=tuple(c))
    surf = warped.extract_surface(algorithm=None)
    p.subplot(0, 0)
    s1 = surf.point_data["max_principal_stress"]
    p.add_mesh(surf, scalars="max_principal_stress", cmap="coolwarm", clim=[-np.abs(s1).max(), np.abs(s1).max()], show_edges=True, edge_color="#555555", line_width=0.3,
               scalar_bar_args={"title": "largest principal stress", "color": "black", "vertical": False, "position_x": 0.2, "width": 0.6})
    what = "cut at its centre across %s" % "xyz"[thin] if a.cut else "surface"
    p.add_text("%s\n%s, displacement x %.3g" % (a.title or os.path.basename(os.path.normpath(a.folder)), what, warp), font_size=10, color="black")
    # Onto the cut (from the kept half's open side), tilted by 35 degrees.
    n_cut = np.eye(3)[thin]
    up_l = np.eye(3)[(thin + 2) % 3]
    d_l = np.cos(np.radians(35)) * n_cut - np.sin(np.radians(35)) * up_l
    p.camera_position = [tuple(c + 2.2 * size * d_l), tuple(c), tuple(up_l)]
    p.subplot(0, 1)
    p.add_mesh(body.extract_feature_edges(feature_angle=30), color="black", line_width=1)
    p.add_mesh(body.extract_surface(algorithm=None), color="#cccccc", opacity=0.12)
    view, up = None, None
    if cracks is not None:
        cr = pv.read(cracks)
        # One side of each separated face (both lie at the same place in the reference shape);
        # faces separated at every corner opaque, those separated at some corners only faint.
        one = cr.extract_cells(np.where(cr.cell_data["side"] == 0)[0])
        n_corners = np.diff(one.cell_offsets)
        full = one.cell_data["cut_corners"] >= n_corners
        top = max(float(one.cell_data["opening"].max()), 1e-300)
        bar = {"title": "crack opening", "color": "black", "vertical": False, "position_x": 0.2, "width": 0.6}
        if full.any():
            p.add_mesh(one.extract_cells(np.where(full)[0]), scalars="opening", cmap="viridis", clim=[0.0, top], show_edges=True, edge_color="#333333", line_width=0.3, scalar_bar_args=bar)
        if (~full).any():
            p.add_mesh(one.extract_cells(np.where(~full)[0]), color="#999999", opacity=0.12)
        p.add_text("crack faces: %d open, %d separated at some corners\nreference shape, seen across the crack" % (full.sum(), (~full).sum()), font_size=10, color="black")
        # Across the crack: along the least-spread direction of its faces' centres, tilted.
        x = one.cell_centers().points
        w, v = np.linalg.eigh(np.cov((x - x.mean(axis=0)).T))
        view = v[:, 0]
        up = v[:, 2]
    else:
        p.add_text("no separated face at this stage", font_size=10, color="black")
    if view is None:
        # Along the body's thinnest direction.
        view = np.eye(3)[thin]
        up = np.eye(3)[(thin + 1) % 3]
    side = np.cross(up, view)
    d = np.cos(np.radians(20)) * view + np.sin(np.radians(20)) * side
    p.camera_position = [tuple(c + 2.5 * size * d), tuple(c), tuple(up)]
    p.screenshot(out)
    print(out)


if __name__ == "__main__":
    main()
