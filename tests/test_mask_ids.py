"""Mask ids per frame for long sequences: while a document's objects fit the uint16 mask they
keep one id each in document order; beyond that, objects never present together share ids, the
limit applies per frame (validate and compose say the same), and masks, the id map and the
labels name the right object on every frame."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from usdscene.document import output_layout as layout
from usdscene.document.model import Camera, FrameInterval, Intrinsics, LensModel, Pose, SceneObject, SceneSpec
from usdscene.errors import DocumentError

REPO = Path(__file__).resolve().parents[1]
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"


def _scene(spans) -> SceneSpec:
    objects = tuple(SceneObject(uid=f"o{k}", name=f"o{k}", class_name="thing",
                                frame_intervals=tuple(FrameInterval(a, b) for a, b in span))
                    for k, span in enumerate(spans))
    return SceneSpec(objects=objects, frame_start=0, frame_end=99)


def test_ids_stay_per_document_while_they_fit():
    scene = _scene([[(0, 9)], [(50, 60)], [], [(20, 30)]])
    assert layout.mask_ids(scene) == {"o0": 1, "o1": 2, "o2": 3, "o3": 4}


def test_objects_never_present_together_share_ids_past_the_limit(monkeypatch):
    monkeypatch.setattr(layout, "MAX_MASK_ID", 2)
    # o0 and o1 leave before o2, o3 arrive, o4 after both; o5 is present on no frame of 0..99.
    scene = _scene([[(0, 9)], [(0, 4), (6, 19)], [(10, 30)], [(20, 40)], [(41, 99)], [(200, 210)]])
    ids = layout.mask_ids(scene)
    assert max(ids.values()) == 2 < len(scene.objects)
    frames_of = {o.uid: {f for f in scene.frames if not o.frame_intervals
                         or any(iv.frame_start <= f <= iv.frame_end for iv in o.frame_intervals)}
                 for o in scene.objects}
    for f in scene.frames:
        present = [ids[uid] for uid, fs in frames_of.items() if f in fs]
        assert len(present) == len(set(present)), f"frame {f}: ids {present} repeat"
    assert ids["o1"] == 2  # one id across its gap (frame 5)


def test_too_many_objects_at_one_frame_is_refused_naming_the_frame(monkeypatch):
    monkeypatch.setattr(layout, "MAX_MASK_ID", 2)
    scene = _scene([[(0, 9)], [(0, 20)], [(15, 30)], [(18, 30)]])
    with pytest.raises(ValueError, match="3 objects present at frame 18 exceed the 2 ids"):
        layout.mask_ids(scene)


def test_id_map_names_the_owner_per_frame():
    class O:  # what the stage reader gives (ObjectEntry's fields used here)
        def __init__(self, uid, mask_id, frames):
            self.uid, self.class_name, self.prim_path = uid, "ball", f"/World/Objects/{uid}"
            self.mask_id, self.visible_frames = mask_id, tuple(frames)

    id_map = json.loads(json.dumps(layout.id_map_json([O("a", 1, range(10)), O("b", 2, [0, 1, 2, 5, 6]),
                                                       O("c", 2, [8, 9])])))
    assert id_map["1"] == {"uid": "a", "class": "ball", "prim": "/World/Objects/a"}
    assert [o["frames"] for o in id_map["2"]] == [[[0, 2], [5, 6]], [[8, 9]]]
    assert layout.mask_owners(id_map, 1) == {1: "a", 2: "b"}
    assert layout.mask_owners(id_map, 9) == {1: "a", 2: "c"}
    assert layout.mask_owners(id_map, 4) == {1: "a"}
    assert {o["uid"] for o in layout.id_map_entries(id_map)} == {"a", "b", "c"}


def _minimal(tmp_path: Path, intervals: dict) -> Path:
    doc = json.loads(MINIMAL.read_text(encoding="utf-8"))
    for uid, (a, b) in intervals.items():
        doc["openlabel"]["objects"][uid]["frame_intervals"] = [{"frame_start": a, "frame_end": b}]
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    for name in ("assets",):
        source = MINIMAL.parent / name
        if source.exists() and not (tmp_path / name).exists():
            (tmp_path / name).symlink_to(source)
    return path


@pytest.mark.usd
def test_validate_and_compose_agree_on_the_per_frame_limit(tmp_path, monkeypatch):
    from usdscene.pipeline import compose_document
    from usdscene.render.stage_reader import read_stage_plan
    from usdscene.validation import validate_document

    monkeypatch.setattr(layout, "MAX_MASK_ID", 2)  # the minimal scene has 3 objects
    # backpack (3) leaves after frame 1, the laptop (4) arrives at frame 2: two at any frame.
    fits = _minimal(tmp_path, {"3": (0, 1), "4": (2, 2)})
    validate_document(fits)
    _, result = compose_document(fits, tmp_path / "out")
    plan = read_stage_plan(result.root_layer)
    ids = {o.uid: o.mask_id for o in plan.objects}
    assert sorted(ids.values()) == [1, 1, 2]
    (crowded := tmp_path / "crowded").mkdir()
    crowded_doc = _minimal(crowded, {"3": (0, 2), "4": (1, 2)})
    with pytest.raises(DocumentError) as gate:
        validate_document(crowded_doc)
    message = "3 objects present at frame 1 exceed the 2 ids of a uint16 mask"
    assert any(message in p.message for p in gate.value.problems)
    with pytest.raises(Exception) as work:
        compose_document(crowded_doc, crowded / "out")
    assert message in str(work.value) or any(message in p.message for p in getattr(work.value, "problems", ()))


@pytest.mark.usd
@pytest.mark.blender
def test_a_shared_id_is_labelled_as_its_owner_on_each_frame(tmp_path):
    from usdscene.dataset.annotation import annotate_output
    from usdscene.render.driver import render
    from usdscene.render.synthetic import SphereSpec, SyntheticScene, write_synthetic_stage

    w, h = 64, 48
    camera = Camera("top", Intrinsics(LensModel.ORTHOGRAPHIC, w, h, 14.0, 14.0, (w - 1) / 2, (h - 1) / 2),
                    pose=Pose.from_rotation_translation(np.diag([1.0, -1.0, -1.0]), (0.0, 0.0, 10.0)))
    # "early" (left) and "late" (right) share id 2 on frames 0-1 and 2-3; "always" has id 1.
    spheres = (SphereSpec("always", (0.0, 0.9, 0.0), 0.4, (0.9, 0.9, 0.9), 1, class_name="ball"),
               SphereSpec("early", (-1.2, -0.5, 0.0), 0.5, (0.9, 0.2, 0.1), 2, class_name="ball", frames=(0, 1)),
               SphereSpec("late", (1.2, -0.5, 0.0), 0.5, (0.1, 0.2, 0.9), 2, class_name="ball", frames=(2, 3)))
    out = tmp_path / "out"
    stage = write_synthetic_stage(SyntheticScene(cameras=(camera,), spheres=spheres, frame_start=0, frame_end=3),
                                  out / "stage")
    render(stage, out, settings_override={"samples": 1, "denoise": False}, progress=False)
    id_map = json.loads((out / layout.ID_MAP_FILE).read_text())
    assert [(o["uid"], o["frames"]) for o in id_map["2"]] == [("early", [[0, 1]]), ("late", [[2, 3]])]
    for f in range(4):  # the id is on the left, then on the right
        mask = cv2.imread(str(layout.mask_path(out, "top", f)), cv2.IMREAD_UNCHANGED)
        xs = np.nonzero(mask == 2)[1]
        assert xs.size and ((xs.mean() < w / 2) == (f < 2)), f"frame {f}"
    _, annotations = annotate_output(out, epsilon_px=0)
    for image in annotations.images:
        uids = {o.uid for o in image.objects}
        assert uids == ({"always", "early"} if image.frame < 2 else {"always", "late"}), image.frame
        two = next(o for o in image.objects if o.mask_id == 2)
        assert two.amodal_box is not None and two.visible_fraction == pytest.approx(1.0, abs=0.05)
