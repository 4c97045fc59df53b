"""Fixture meshes (trimesh) and ArUco tag textures, written to ``assets/``.

Each mesh is modelled in the frame it is attached to (see :mod:`simgap.core.rig`), in metres:

========================  ===========  ====================================================
file                      frame        what
========================  ===========  ====================================================
``table.ply``             rail         table top and a backdrop wall behind the turntable
``rail.ply``              rail         the linear rail under the carriage
``carriage.ply``          carriage     carriage plate and the post holding the camera
``camera_body.ply``       eyepoint     RealSense D435i body, its front face at the eyepoint
``turntable.ply``         turntable    the turntable disc, top face at z = 0
``node.ply``              turntable    the tri-truss node block carrying both tags
``tag_<id>.png``          —            marker with its white quiet zone, one pixel per cell
========================  ===========  ====================================================

Run ``simgap assets`` (or ``python -m simgap.render.assets``) to regenerate them.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import trimesh

from simgap.core.aruco import BORDER_CELLS, marker_cells, predefined_dictionary
from simgap.core.atomic import atomic_write
from simgap.core.paths import assets_dir
from simgap.core.rig import Rig, load_rig
from simgap.scene.spec import TABLE_TOP_Z_M

#: Gap between a tag sticker and the node face behind it (m): the sticker's thickness.
STICKER_STANDOFF = 0.0003


def _box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(
        extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2)
    )


def fixture_meshes(rig: Rig) -> dict[str, trimesh.Trimesh]:
    """Build the fixture meshes for ``rig``, each in its own frame (m)."""
    links = rig.links
    eye_in_carriage = -np.asarray(links.eyepoint_to_carriage)
    tt_z = links.carriage_to_turntable[2]
    r_in = min(f.radius for f in rig.tags.faces) + STICKER_STANDOFF
    r_out = max(f.radius for f in rig.tags.faces) - STICKER_STANDOFF
    y_far = links.carriage_to_turntable[1] + 0.6
    body_bottom = eye_in_carriage[2] - 0.0125
    turntable = trimesh.creation.cylinder(radius=0.1, height=tt_z, sections=256)
    turntable.apply_translation((0, 0, -tt_z / 2))
    return {
        "table": trimesh.util.concatenate(
            [
                _box((-0.8, -0.8, TABLE_TOP_Z_M - 0.01), (0.8, y_far, TABLE_TOP_Z_M)),
                _box((-0.8, y_far, TABLE_TOP_Z_M - 0.01), (0.8, y_far + 0.02, 0.6)),
            ]
        ),
        "rail": _box((-0.015, -0.45, -0.02), (0.015, 0.08, 0.0)),
        "carriage": trimesh.util.concatenate(
            [
                _box((-0.03, -0.03, 0.0), (0.03, 0.045, 0.008)),
                _box(
                    (-0.004, eye_in_carriage[1] - 0.022, 0.008),
                    (0.012, eye_in_carriage[1] - 0.004, body_bottom),
                ),
            ]
        ),
        "camera_body": _box((-0.0625, -0.0255, -0.0125), (0.0275, -0.0005, 0.0125)),
        "turntable": turntable,
        "node": _box((-0.025, -r_out, 0.0), (0.025, -r_in, 0.08)),
    }


def tag_texture(dictionary: str, tag_id: int, quiet_zone_cells: int) -> np.ndarray:
    """Marker image with its quiet zone, one pixel per cell, uint8 (0 = black, 255 = white)."""
    d = predefined_dictionary(dictionary)
    cells = marker_cells(dictionary)
    marker = cv2.aruco.generateImageMarker(d, tag_id, cells, borderBits=BORDER_CELLS)
    return np.pad(marker, quiet_zone_cells, constant_values=255)


def write_assets(rig: Rig | None = None, out: Path | None = None) -> list[Path]:
    """Write fixture meshes (PLY) and tag textures (PNG) atomically; return the written paths."""
    rig = rig or load_rig()
    out = Path(out or assets_dir())
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, mesh in fixture_meshes(rig).items():
        path = out / f"{name}.ply"
        atomic_write(path, lambda tmp, m=mesh: m.export(tmp, file_type="ply", encoding="binary"))
        written.append(path)
    for face in rig.tags.faces:
        path = out / f"tag_{face.id}.png"
        texture = tag_texture(rig.tags.dictionary, face.id, rig.tags.quiet_zone_cells)
        ok, buf = cv2.imencode(".png", texture)
        if not ok:
            raise OSError(f"{path}: could not encode the tag texture")
        atomic_write(path, buf.tobytes())
        written.append(path)
    return written


if __name__ == "__main__":
    for p in write_assets():
        print(p)
