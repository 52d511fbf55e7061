"""Test inputs for CAD import, made here: STEP text (tiny valid AP214 B-reps of boxes and a
cylinder), DXF documents through ezdxf, meshes exported by trimesh; and the box check."""

from __future__ import annotations

import io
import itertools
from pathlib import Path

import ezdxf
import numpy as np
import pytest
import trimesh

DATA = Path(__file__).parent / "data" / "cad"


# -- STEP text writers (tiny valid AP214 B-reps) ------------------------------------------------


class _Step:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def add(self, s: str) -> str:
        self.lines.append(f"#{len(self.lines) + 1}={s};")
        return f"#{len(self.lines)}"

    def pt(self, p) -> str:
        x, y, z = (float(v) for v in p)
        return self.add(f"CARTESIAN_POINT('',({x!r},{y!r},{z!r}))")

    def dir(self, d) -> str:
        x, y, z = (float(v) for v in d)
        return self.add(f"DIRECTION('',({x!r},{y!r},{z!r}))")

    def axis(self, o, z, x) -> str:
        return self.add(f"AXIS2_PLACEMENT_3D('',{self.pt(o)},{self.dir(z)},{self.dir(x)})")

    def face(self, edges, surface) -> str:
        oes = [self.add(f"ORIENTED_EDGE('',*,*,{e},{s})") for e, s in edges]
        loop = self.add(f"EDGE_LOOP('',({','.join(oes)}))")
        bound = self.add(f"FACE_OUTER_BOUND('',{loop},.T.)")
        return self.add(f"ADVANCED_FACE('',({bound}),{surface},.T.)")

    def document(self, solids_fn, unit: str) -> str:
        app = self.add("APPLICATION_CONTEXT('automotive design')")
        self.add(f"APPLICATION_PROTOCOL_DEFINITION('international standard',"
                 f"'automotive_design',2000,{app})")
        pc = self.add(f"PRODUCT_CONTEXT('',{app},'mechanical')")
        pr = self.add(f"PRODUCT('part','part','',({pc}))")
        pf = self.add(f"PRODUCT_DEFINITION_FORMATION('','',{pr})")
        pdc = self.add(f"PRODUCT_DEFINITION_CONTEXT('part definition',{app},'design')")
        pd = self.add(f"PRODUCT_DEFINITION('design','',{pf},{pdc})")
        pds = self.add(f"PRODUCT_DEFINITION_SHAPE('','',{pd})")
        if unit == "inch":
            mm = self.add("(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.))")
            lm = self.add(f"LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),{mm})")
            dim = self.add("DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.)")
            lu = self.add(f"(CONVERSION_BASED_UNIT('INCH',{lm}) LENGTH_UNIT() NAMED_UNIT({dim}))")
        else:
            prefix = {"mm": ".MILLI.", "m": "$", "cm": ".CENTI."}[unit]
            lu = self.add(f"(LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT({prefix},.METRE.))")
        au = self.add("(NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.))")
        su = self.add("(NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT())")
        unc = self.add(f"UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),{lu},"
                       "'distance_accuracy_value','')")
        ctx = self.add(f"(GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT"
                       f"(({unc})) GLOBAL_UNIT_ASSIGNED_CONTEXT(({lu},{au},{su})) "
                       "REPRESENTATION_CONTEXT('',''))")
        solids = solids_fn(self)
        origin = self.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))
        rep = self.add(f"ADVANCED_BREP_SHAPE_REPRESENTATION('',({','.join(solids)},{origin}),"
                       f"{ctx})")
        self.add(f"SHAPE_DEFINITION_REPRESENTATION({pds},{rep})")
        return ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('part'),'2;1');\n"
                "FILE_NAME('part.step','2024-01-01T00:00:00',(''),(''),'','','');\n"
                "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\n"
                "DATA;\n" + "\n".join(self.lines) + "\nENDSEC;\nEND-ISO-10303-21;\n")


def _box_solid(s: _Step, lo, hi) -> str:
    corner = {k: tuple(hi[i] if k[i] else lo[i] for i in range(3))
              for k in itertools.product((0, 1), repeat=3)}
    vert = {k: s.add(f"VERTEX_POINT('',{s.pt(p)})") for k, p in corner.items()}
    edges: dict = {}

    def edge(a, b):
        if (b, a) in edges:
            return edges[(b, a)], ".F."
        if (a, b) not in edges:
            d = np.subtract(corner[b], corner[a])
            n = float(np.linalg.norm(d))
            vec = s.add(f"VECTOR('',{s.dir(d / n)},{n!r})")
            line = s.add(f"LINE('',{s.pt(corner[a])},{vec})")
            edges[(a, b)] = s.add(f"EDGE_CURVE('',{vert[a]},{vert[b]},{line},.T.)")
        return edges[(a, b)], ".T."

    faces = []
    for ax in range(3):
        u, v = (ax + 1) % 3, (ax + 2) % 3
        for side in (0, 1):
            uv = [(0, 0), (1, 0), (1, 1), (0, 1)]
            uv = uv if side else uv[::-1]  # counter-clockwise about the outward normal
            keys = []
            for a, b in uv:
                k = [0, 0, 0]
                k[ax], k[u], k[v] = side, a, b
                keys.append(tuple(k))
            normal = [0, 0, 0]
            normal[ax] = 1 if side else -1
            ref = [0, 0, 0]
            ref[u] = 1
            plane = s.add(f"PLANE('',{s.axis(corner[keys[0]], normal, ref)})")
            faces.append(s.face([edge(keys[i], keys[(i + 1) % 4]) for i in range(4)], plane))
    shell = s.add(f"CLOSED_SHELL('',({','.join(faces)}))")
    return s.add(f"MANIFOLD_SOLID_BREP('',{shell})")


def step_boxes(boxes, unit: str = "mm") -> bytes:
    """STEP text of axis-aligned boxes [(lo, hi), ...] in the given unit."""
    return _Step().document(lambda s: [_box_solid(s, lo, hi) for lo, hi in boxes],
                            unit).encode()


def step_cylinder(r: float, h: float, unit: str = "mm") -> bytes:
    """STEP text of a cylinder (radius r, height h along z from z=0): curved faces and seams."""

    def solid(s: _Step) -> list[str]:
        v0 = s.add(f"VERTEX_POINT('',{s.pt((r, 0, 0))})")
        v1 = s.add(f"VERTEX_POINT('',{s.pt((r, 0, h))})")
        c0 = s.add(f"CIRCLE('',{s.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))},{float(r)!r})")
        c1 = s.add(f"CIRCLE('',{s.axis((0, 0, h), (0, 0, 1), (1, 0, 0))},{float(r)!r})")
        e0 = s.add(f"EDGE_CURVE('',{v0},{v0},{c0},.T.)")
        e1 = s.add(f"EDGE_CURVE('',{v1},{v1},{c1},.T.)")
        vec = s.add(f"VECTOR('',{s.dir((0, 0, 1))},{float(h)!r})")
        seam = s.add(f"EDGE_CURVE('',{v0},{v1},{s.add(f'LINE({chr(39) * 2},{s.pt((r, 0, 0))},{vec})')},.T.)")  # noqa: E501
        bottom = s.face([(e0, ".F.")], s.add(f"PLANE('',{s.axis((0, 0, 0), (0, 0, -1), (1, 0, 0))})"))  # noqa: E501
        top = s.face([(e1, ".T.")], s.add(f"PLANE('',{s.axis((0, 0, h), (0, 0, 1), (1, 0, 0))})"))
        surf = s.add(f"CYLINDRICAL_SURFACE('',{s.axis((0, 0, 0), (0, 0, 1), (1, 0, 0))},"
                     f"{float(r)!r})")
        side = s.face([(e0, ".T."), (seam, ".T."), (e1, ".F."), (seam, ".F.")], surf)
        shell = s.add(f"CLOSED_SHELL('',({bottom},{top},{side}))")
        return [s.add(f"MANIFOLD_SOLID_BREP('',{shell})")]

    return _Step().document(solid, unit).encode()


# -- helpers -------------------------------------------------------------------------------------


def _export(mesh_or_scene, file_type: str) -> bytes:
    data = mesh_or_scene.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


def _box_mm() -> trimesh.Trimesh:
    """A 40 x 30 x 20 part in millimetre numbers, off-centre so frames matter."""
    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    box.apply_translation((100.0, 50.0, 10.0))
    return box


def _dxf(build, insunits: int = 4) -> bytes:
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = insunits
    build(doc, doc.modelspace())
    s = io.StringIO()
    doc.write(s)
    return s.getvalue().encode()


def _assert_box_m(result, extents_m, volume_m3=None) -> None:
    np.testing.assert_allclose(result.mesh.extents, extents_m, rtol=1e-6)
    assert result.mesh.is_watertight
    if volume_m3 is not None:
        assert result.mesh.volume == pytest.approx(volume_m3, rel=1e-5)


# -- every format, with the unit each one implies -------------------------------------------------
