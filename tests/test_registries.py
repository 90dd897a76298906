"""A new export format is one writer module plus one registry entry: the command line, the
document's validation and ``export_formats`` take it with no other module touched. A new lens
is one class and one ``register`` call: projection, rays and the render's remap follow it."""

from __future__ import annotations

import json
import textwrap

import pytest

from usdscene.converters.exports.registry import (FORMATS, MOVING_SEQUENCE, ExportFormat, format_names,
                                                   register)
from usdscene.document import output_layout as layout
from usdscene.errors import OutputError

pytestmark = pytest.mark.unit

TOY_WRITER = textwrap.dedent('''
    """A toy export: one line per object of the document."""
    from usdscene.files import write_text_atomic


    def write_toy(job):
        objects = job.document["openlabel"].get("objects", {})
        target = job.out_dir / "exports" / "toy.txt"
        write_text_atomic(target, "".join(f"{uid} {o['type']}\\n" for uid, o in sorted(objects.items())))
        return target
''')


def _document(fps=None) -> dict:
    usdscene = {} if fps is None else {"usdscene": {"fps": fps}}
    return {"openlabel": {
        "metadata": {"schema_version": "1.0.0", "name": "toy", **usdscene},
        "objects": {"1": {"name": "bag_1", "type": "backpack"}, "0": {"name": "case_0", "type": "suitcase"}},
    }}


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """The toy formats, registered for one test: ``toy`` and ``toy_moving`` (needs a moving sequence)."""
    (tmp_path / "toy_writer.py").write_text(TOY_WRITER, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    register(ExportFormat("toy", "toy rows", writer="toy_writer:write_toy"))
    register(ExportFormat("toy_moving", "toy rows of tracks", writer="toy_writer:write_toy",
                          needs=frozenset({MOVING_SEQUENCE})))
    yield
    del FORMATS["toy"], FORMATS["toy_moving"]


def _out(tmp_path, document) -> object:
    out = tmp_path / "out"
    out.mkdir(parents=True)
    (out / layout.ANNOTATIONS_FILE).write_text(json.dumps(document), encoding="utf-8")
    return out


def test_toy_format_exports_through_the_library_and_the_command_line(toy, tmp_path, capsys):
    from usdscene.cli import main
    from usdscene.dataset.export import ExportOptions, export_formats

    out = _out(tmp_path, _document())
    written = export_formats(out, ["toy"], ExportOptions(document_classes=True))
    assert written == {"toy": out / "exports" / "toy.txt"}
    assert written["toy"].read_text() == "0 suitcase\n1 backpack\n"
    written["toy"].unlink()
    assert main(["export", "toy", str(out), "--document-classes"]) == 0
    assert f"toy: {out / 'exports' / 'toy.txt'}" in capsys.readouterr().out
    assert written["toy"].read_text() == "0 suitcase\n1 backpack\n"


def test_toy_format_is_a_valid_document_export(toy):
    from usdscene.converters.openlabel.load import DocumentBody
    from usdscene.converters.openlabel.metadata import read_metadata

    for names, problems in ((["toy", "coco"], []), (["toyy"], ["openlabel.metadata.usdscene.exports[0]"])):
        document = _document()
        document["openlabel"]["metadata"]["usdscene"] = {"exports": names}
        body = DocumentBody(document["openlabel"])
        assert list(read_metadata(body)["exports"]) == names
        assert [p.where for p in body.problems.problems] == problems
        if problems:
            assert f"expected one of {', '.join(format_names())}" in body.problems.problems[0].message
            assert "toy" in body.problems.problems[0].message


def test_a_need_is_checked_before_anything_is_written(toy, tmp_path):
    from usdscene.dataset.export import ExportOptions, export_formats

    out = _out(tmp_path, _document())
    with pytest.raises(OutputError, match="the toy_moving export needs tracks"):
        export_formats(out, ["toy", "toy_moving"], ExportOptions(document_classes=True))
    assert not (out / "exports").exists()
    moving = _out(tmp_path / "moving", _document(fps=5.0))
    assert set(export_formats(moving, ["toy_moving"], ExportOptions(document_classes=True))) == {"toy_moving"}


def test_a_name_is_registered_once_and_needs_are_known(toy):
    with pytest.raises(ValueError, match="registered already"):
        register(ExportFormat("toy", "again", writer="toy_writer:write_toy"))
    with pytest.raises(ValueError, match="known needs"):
        register(ExportFormat("toy_depth", "depth", writer="toy_writer:write_toy", needs=frozenset({"depth"})))
    assert "toy_depth" not in FORMATS


def test_built_in_formats_are_the_registry():
    assert format_names()[:5] == ("coco", "yolo", "rois", "mot", "multiview")
    assert [n for n, f in FORMATS.items() if f.dataset] == ["coco", "yolo"]
    assert {n for n, f in FORMATS.items() if MOVING_SEQUENCE in f.needs} == {"mot", "multiview"}
    from dataclasses import fields

    from usdscene.dataset.export import ExportOptions

    known = {f.name for f in fields(ExportOptions)}
    for fmt in FORMATS.values():
        assert set(fmt.options) <= known, fmt.name


@pytest.fixture
def toy_lens():
    import numpy as np

    from usdscene.lens import LENSES, register
    from usdscene.lens.fisheye import RadialLens

    class Stereographic(RadialLens):
        name = "toy_stereographic"

        def radius(self, theta, coeffs):
            return 2.0 * np.tan(theta / 2.0), theta < np.pi

        def angle(self, radius, intrinsics, iterations):
            return 2.0 * np.arctan(radius / 2.0), np.ones(len(radius), dtype=bool)

    register(Stereographic())
    yield "toy_stereographic"
    del LENSES["toy_stereographic"]


def test_toy_lens_projects_and_renders_through_the_registry_alone(toy_lens):
    import math

    import numpy as np

    from usdscene.document.model import Intrinsics, LensModel
    from usdscene.labels.projection import (native_renderable, pixel_rays, project_camera_points, remap_grids,
                                            undistorted_render_intrinsics)

    intr = Intrinsics(toy_lens, 64, 48, 20.0, 20.0, 31.5, 23.5, fov_deg=200.0)
    theta = np.radians([0.0, 30.0, 60.0, 95.0, 120.0])
    points = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
    uv, valid = project_camera_points(intr, points)
    assert valid.tolist() == [True, True, True, True, False]  # 120° lies beyond the 100° half field
    assert np.allclose(uv[:4, 0] - 31.5, 2.0 * 20.0 * np.tan(theta[:4] / 2.0))
    rays, ok = pixel_rays(intr, uv[:4])
    assert ok.all() and np.allclose(rays, points[:4])
    assert not native_renderable(intr)
    render = undistorted_render_intrinsics(intr)
    # The image's corners see 90° off the axis: an equidistant render holds that and a margin.
    assert render.lens is LensModel.FISHEYE_EQUIDISTANT and 180.0 <= render.fov_deg <= 184.0
    map_x, map_y = remap_grids(intr, render)
    for u, v in ((32, 24), (63, 24), (5, 40)):
        dx, dy = u - 31.5, v - 23.5
        r = math.hypot(dx, dy)
        seen = 20.0 * 2.0 * math.atan(r / 40.0)  # the equidistant radius of the pixel's ray
        assert math.isclose(float(map_x[v, u]), render.cx_px + dx / r * seen, abs_tol=1e-3)
        assert math.isclose(float(map_y[v, u]), render.cy_px + dy / r * seen, abs_tol=1e-3)


def test_a_lens_name_is_registered_once():
    from usdscene.lens import Lens, lens_for, register
    from usdscene.lens.pinhole import Perspective

    assert lens_for("perspective") is lens_for(Perspective.name)
    with pytest.raises(ValueError, match="registered already"):
        register(Perspective())
    with pytest.raises(ValueError, match="no name"):
        register(Lens())
