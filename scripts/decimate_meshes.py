"""Write a light Baxter (decimated meshes + URDF) into ``urdf/`` once; the studio draws it by default.

Why: the example-robot-data meshes have ~410,000 triangles. Software WebGL in a browser without a GPU
(headless Chromium in the tests, many laptops in a VM) then draws about 1.4 frames per second and every
click waits on the page. Quadric decimation of each coloured part to ~10% keeps Baxter's look (red
links, dark joints, grey gripper) at a few tens of thousands of triangles.

The decimation drops the per-part colours (the COLLADA files carry them as material colours), so each
part's colour is read before and painted back afterwards. Parts are written as binary glTF (``.glb``)
with the colours inside, and a copy of the URDF points at them with paths relative to ``urdf/``.

Usage::

    python scripts/decimate_meshes.py            # writes urdf/baxter_light.urdf and urdf/meshes/
    python scripts/decimate_meshes.py --keep 0.1 --min-faces 150

Needs ``trimesh`` and ``fast-simplification`` (``pip install -e .[mesh]``); run again only when the
upstream meshes change.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from studio.core.kinematics import baxter_urdf_path, package_share_dir  # noqa: E402

OUT_DIR = ROOT / "urdf"
OUT_URDF = OUT_DIR / "baxter_light.urdf"
PACKAGE_PREFIX = "package://"

#: Parts whose quadric decimation tears holes into the surface (non-manifold CAD exports): the torso and
#: pedestal. They are replaced by the lighter collision shells the URDF already ships, which look the same
#: at studio scale.
REPLACE_WITH_COLLISION = {
    "torso/base_link.DAE": "torso/base_link_collision.DAE",
    "base/PEDESTAL.DAE": "base/pedestal_link_collision.DAE",
}


def resolve(uri: str) -> Path:
    if uri.startswith(PACKAGE_PREFIX):
        return package_share_dir() / uri[len(PACKAGE_PREFIX) :]
    return baxter_urdf_path().parent / uri


def _rgba(visual: trimesh.visual.base.Visuals | None, fallback: np.ndarray) -> np.ndarray:
    """The single colour (RGBA uint8) a part is painted in."""
    if visual is None:
        return fallback
    kind = visual.kind
    if kind == "texture" and getattr(visual, "material", None) is not None:
        mat = visual.material
        col = getattr(mat, "main_color", None)
        if col is not None:
            return np.asarray(col, dtype=np.uint8)
    if kind == "face":
        return np.asarray(visual.face_colors[0], dtype=np.uint8)
    if kind == "vertex":
        return np.asarray(visual.vertex_colors[0], dtype=np.uint8)
    return fallback


def _urdf_material_colors(root: ET.Element) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for mat in root.iter("material"):
        col = mat.find("color")
        if col is not None and mat.get("name"):
            rgba = np.array([float(v) for v in col.get("rgba", "0.5 0.5 0.5 1").split()])
            out[mat.get("name", "")] = np.clip(np.round(rgba * 255), 0, 255).astype(np.uint8)
    return out


def decimate_file(src: Path, dst: Path, keep: float, min_faces: int, fallback: np.ndarray) -> tuple[int, int]:
    """Decimate every part of ``src`` to ``keep`` of its faces and write a coloured GLB to ``dst``.

    Returns (faces before, faces after).
    """
    loaded = trimesh.load(str(src), force="scene")
    parts = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    out = trimesh.Scene()
    before = after = 0
    for i, part in enumerate(parts):
        if not isinstance(part, trimesh.Trimesh) or len(part.faces) == 0:
            continue
        color = _rgba(part.visual, fallback)
        mesh = trimesh.Trimesh(vertices=part.vertices.copy(), faces=part.faces.copy(), process=True)
        mesh.merge_vertices()
        n = len(mesh.faces)
        before += n
        target = max(min_faces, int(n * keep))
        if n > target:
            mesh = mesh.simplify_quadric_decimation(face_count=target)
        mesh.visual = trimesh.visual.ColorVisuals(mesh=mesh, face_colors=np.tile(color, (len(mesh.faces), 1)))
        after += len(mesh.faces)
        out.add_geometry(mesh, geom_name=f"{src.stem}_{i}")
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(out.export(file_type="glb"))
    return before, after


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=float, default=0.1, help="fraction of faces to keep per part (default 0.1)")
    ap.add_argument("--min-faces", type=int, default=120, help="never decimate a part below this many faces")
    args = ap.parse_args(argv)

    src_urdf = baxter_urdf_path()
    tree = ET.parse(src_urdf)
    root = tree.getroot()
    materials = _urdf_material_colors(root)
    done: dict[str, str] = {}
    total_before = total_after = 0
    for link in root.iter("link"):
        # The studio never draws collision geometry; dropping it keeps the light URDF self-contained.
        for col in list(link.findall("collision")):
            link.remove(col)
        for vis in link.findall("visual"):
            mesh_el = vis.find("geometry/mesh")
            if mesh_el is None:
                continue
            uri = mesh_el.get("filename", "")
            rel = uri.split("/meshes/", 1)[1] if "/meshes/" in uri else Path(uri).name
            if rel not in done:
                src_rel = REPLACE_WITH_COLLISION.get(rel, rel)
                src = resolve(uri.replace(rel, src_rel))
                fallback = np.array([128, 128, 128, 255], dtype=np.uint8)
                mat = vis.find("material")
                if mat is not None:
                    col = mat.find("color")
                    if col is not None:
                        fallback = np.clip(
                            np.round(np.array([float(v) for v in col.get("rgba", "").split()]) * 255), 0, 255
                        ).astype(np.uint8)
                    elif mat.get("name") in materials:
                        fallback = materials[mat.get("name", "")]
                dst_rel = "meshes/" + str(Path(rel).with_suffix(".glb"))
                keep = 1.0 if rel in REPLACE_WITH_COLLISION else args.keep
                b, a = decimate_file(src, OUT_DIR / dst_rel, keep, args.min_faces, fallback)
                total_before += b
                total_after += a
                done[rel] = dst_rel
                print(f"{rel:45s} {b:7d} -> {a:6d} faces")
            mesh_el.set("filename", done[rel])
    ET.indent(tree)
    header = (
        "<!-- Light Baxter for the Teaching Studio, generated by scripts/decimate_meshes.py from\n"
        "     example-robot-data's baxter.urdf: same links and joints, decimated coloured meshes. -->\n"
    )
    body = ET.tostring(root, encoding="unicode")
    OUT_URDF.write_text('<?xml version="1.0"?>\n' + header + body + "\n")
    print(f"unique meshes: {total_before} -> {total_after} faces; wrote {OUT_URDF.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
