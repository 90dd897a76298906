"""The camera-design route keeps what the stage route keeps: document → ``usdscene blend`` →
(cameras moved, renamed, an object deleted in Blender) → ``export-openlabel scene.blend`` gives
back the places, relations, ROI rules, render settings and other people's content that
``compose`` → ``export-openlabel STAGE`` gives back, with Blender's edits. Blender's USD
exporter writes neither customData nor customLayerData, so the .blend carries them itself."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.usd, pytest.mark.blender]

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"


@pytest.fixture(scope="module")
def routes(tmp_path_factory):
    """(folder, the stage route's document, the .blend) of the minimal example with foreign
    keys added at the top, on a camera, an object and a relation."""
    from usdscene.cli import main

    folder = tmp_path_factory.mktemp("carry")
    document = json.loads(MINIMAL.read_text(encoding="utf-8"))
    body = document["openlabel"]
    body["metadata"]["acme_project"] = {"batch": 7}
    body["streams"]["cam_01"]["acme_mount"] = "pole 3"
    body["objects"]["3"]["acme_tag"] = "inspect"
    body["relations"]["0"]["acme_confidence"] = 0.9
    doc = folder / "scene.openlabel.json"
    doc.write_text(json.dumps(document), encoding="utf-8")
    assert main(["compose", str(doc), "-o", str(folder / "out")]) == 0
    assert main(["export-openlabel", str(folder / "out" / "stage"), "-o", str(folder / "stage.json")]) == 0
    blend = folder / "scene.blend"
    assert main(["blend", str(doc), "-o", str(blend)]) == 0
    return folder, json.loads((folder / "stage.json").read_text(encoding="utf-8")), blend


def _edit(blend: Path, out: Path, body: str) -> Path:
    """``out``: ``blend`` after the bpy statements ``body`` ran on it (in a separate process)."""
    script = "import bpy\nbpy.ops.wm.open_mainfile(filepath=%r)\n%s\nbpy.ops.wm.save_as_mainfile(filepath=%r)\n" % (
        str(blend), textwrap.dedent(body), str(out))
    subprocess.run([sys.executable, "-c", script], check=True, capture_output=True)
    return out


def test_unedited_blend_gives_back_the_stage_routes_document(routes):
    from usdscene.cli import main

    folder, stage_doc, blend = routes
    assert main(["export-openlabel", str(blend), "-o", str(folder / "blend.json")]) == 0
    blend_doc = json.loads((folder / "blend.json").read_text(encoding="utf-8"))
    body = blend_doc["openlabel"]
    assert body["relations"]["0"]["acme_confidence"] == 0.9
    assert body["metadata"]["usdscene"]["roi_rules"] == {"is_below": "correct", "is_on": "incorrect"}
    assert blend_doc == stage_doc


def test_blend_edited_in_blender_keeps_carried_content(routes, tmp_path):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.render.blend_io import scene_from_blend

    folder, stage_doc, blend = routes
    edited = _edit(blend, tmp_path / "edited.blend", """
        bpy.data.objects["cam_01"].location.z += 0.5
        bpy.data.objects["cam_02"].name = "fisheye_new"
        doomed = [ob for ob in bpy.data.objects if ob.get("usdscene_uid") == "5"]
        for ob in [m for ob in doomed for m in (ob, *ob.children_recursive)]:
            bpy.data.objects.remove(ob, do_unlink=True)
    """)
    want = read_openlabel(stage_doc)
    got = scene_from_blend(edited)
    assert got.places == want.places and got.places
    assert got.relations == want.relations and "acme_confidence" in got.relations[0].extra
    assert got.roi_rules == want.roi_rules and got.roi_ignore == want.roi_ignore
    assert got.extra == want.extra and "acme_project" in got.extra
    assert got.render == want.render and got.seed == want.seed and got.exports == want.exports
    assert got.lights == want.lights
    cameras, before = {c.name: c for c in got.cameras}, {c.name: c for c in want.cameras}
    assert sorted(cameras) == ["cam_01", "fisheye_new"]
    moved = cameras["cam_01"]
    np.testing.assert_allclose(moved.pose.translation_m, before["cam_01"].pose.translation_m + [0.0, 0.0, 0.5],
                               atol=1e-5)
    np.testing.assert_allclose(moved.pose.rotation, before["cam_01"].pose.rotation, atol=1e-5)
    assert moved.extra == before["cam_01"].extra and "acme_mount" in moved.extra
    assert moved.intrinsics == before["cam_01"].intrinsics
    assert (moved.description, moved.model_name) == (before["cam_01"].description, before["cam_01"].model_name)
    renamed = cameras["fisheye_new"]  # renamed in Blender: keeps its content and exact pose
    assert renamed.description == before["cam_02"].description != ""
    assert renamed.pose == before["cam_02"].pose and renamed.intrinsics == before["cam_02"].intrinsics
    objects = {o.uid: o for o in got.objects}
    assert sorted(objects) == ["3", "4"]  # the passenger was deleted in Blender
    assert objects["3"] == {o.uid: o for o in want.objects}["3"]  # untouched: exact, carried key kept
    assert "acme_tag" in objects["3"].extra


def test_blend_without_or_with_a_broken_carried_document(routes, tmp_path):
    from usdscene.errors import DocumentError
    from usdscene.render.blend_io import scene_from_blend

    _, _, blend = routes
    plain = _edit(blend, tmp_path / "plain.blend", 'del bpy.context.scene["usdscene_document"]')
    scene = scene_from_blend(plain)  # as Blender exports it: objects and cameras, no relations
    assert sorted(o.uid for o in scene.objects) == ["3", "4", "5"]
    assert sorted(c.name for c in scene.cameras) == ["cam_01", "cam_02"]
    assert scene.relations == () and scene.places == ()
    broken = _edit(blend, tmp_path / "broken.blend", 'bpy.context.scene["usdscene_document"] = "{oops"')
    with pytest.raises(DocumentError, match="usdscene_document"):
        scene_from_blend(broken)


def test_deleting_an_object_in_blender_drops_its_relations_and_renaming_keeps_its_content(routes, tmp_path):
    from usdscene.converters.openlabel import read_openlabel
    from usdscene.render.blend_io import scene_from_blend

    _, stage_doc, blend = routes
    edited = _edit(blend, tmp_path / "edited.blend", """
        roots = [ob for ob in bpy.data.objects if ob.get("usdscene_uid") in ("3", "5")]
        for ob in roots:
            if ob["usdscene_uid"] == "5":
                ob.name = "renamed_passenger"
            else:
                for member in (ob, *ob.children_recursive):
                    bpy.data.objects.remove(member, do_unlink=True)
    """)
    want = {o.uid: o for o in read_openlabel(stage_doc).objects}
    got = scene_from_blend(edited)
    assert sorted(o.uid for o in got.objects) == ["4", "5"]
    assert got.relations == ()  # "backpack is_below seat" named the deleted backpack
    assert got.places == read_openlabel(stage_doc).places
    assert {o.uid: o for o in got.objects}["5"] == want["5"]  # appearance, pose variant, name kept
