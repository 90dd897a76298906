"""The Ray executor on a real multi-node Ray cluster on this machine (a head and two worker
nodes, 1 CPU each): the minimal example rendered with one Ray worker killed mid-run gives
byte-identical images, masks, annotations and exports to the local executor, and a run
started with one executor resumes with the other."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from usdscene.document import output_layout as layout

REPO = Path(__file__).resolve().parent.parent
MINIMAL = REPO / "examples" / "minimal" / "scene.openlabel.json"
STORE_BYTES = 80 * 1024 * 1024  # per node; the minimal stage bundle is ~2 MB

pytestmark = [pytest.mark.usd, pytest.mark.blender, pytest.mark.ray, pytest.mark.slow]


@pytest.fixture(scope="module")
def cluster():
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={
        "num_cpus": 1, "include_dashboard": False, "object_store_memory": STORE_BYTES})
    for _ in range(2):
        cluster.add_node(num_cpus=1, object_store_memory=STORE_BYTES)
    cluster.wait_for_nodes()
    yield cluster
    cluster.shutdown()


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    from usdscene.pipeline import RunOptions, run_pipeline

    out = tmp_path_factory.mktemp("local") / "out"
    run_pipeline(MINIMAL, out, RunOptions(exports=["coco"]), progress=False)
    return out


def _products(out: Path) -> dict[str, bytes]:
    files = [*out.glob("images/*/*.png"), *out.glob("masks/*/*.png"), out / layout.ID_MAP_FILE,
             out / "annotations.openlabel.json", *sorted((out / "exports").rglob("*.json"))]
    return {str(p.relative_to(out)): p.read_bytes() for p in files}


def test_ray_cluster_with_a_killed_worker_matches_local_byte_for_byte(cluster, local_run, tmp_path):
    from usdscene.pipeline import RunOptions, run_pipeline
    from usdscene.render.driver import render
    from usdscene.render.ray_executor import RayExecutor

    out = tmp_path / "out"
    # Two slots: frame 1 (two images) as one shard, frame 2 as two of one image, on 2-3 nodes.
    # Frame 0 with the local executor; the Ray run must resume from there.
    first = run_pipeline(MINIMAL, out, RunOptions(frames=[0], exports=[]), progress=False)
    assert first.images_written == 2

    ray_workers: dict[str, int] = {}
    killed: list[int] = []

    def kill_a_ray_worker(event: dict) -> None:
        if event.get("event") == "started":
            ray_workers[event["node"]] = event["pid"]
        elif event.get("event") == "imported" and not killed:
            # The worker of this task has imported the stage and renders its first image
            # (finished images are reported one render late, so this is the one sure moment
            # with work left). Kill the task's Ray worker process; the Blender worker under it
            # dies with it.
            killed.append(ray_workers[event["node"]])
            os.kill(killed[0], signal.SIGKILL)

    report = render(out / "stage" / "scene.usda", out, progress=False, on_event=kill_a_ray_worker,
                    executor=RayExecutor(cluster.address, max_slots=2))
    assert killed, "no Ray worker was killed"
    assert report.executor == "ray"
    assert report.pairs_skipped == 2 and report.pairs_rendered == 4
    assert report.retries >= 1
    assert len(report.nodes) >= 2, report.nodes
    assert sum(n["images"] for n in report.nodes.values()) == 4

    # Back to the local executor: nothing left to render; labels and exports are written.
    last = run_pipeline(MINIMAL, out, RunOptions(exports=["coco"]), progress=False)
    assert last.images_written == 0 and last.images_skipped == 6
    got, expected = _products(out), _products(local_run)
    assert sorted(got) == sorted(expected) and len(got) >= 15
    for name, data in expected.items():
        assert got[name] == data, f"{name} differs between the Ray and the local executor"
    assert not list(out.rglob("*.tmp"))


def test_cli_ray_executor_resumes_and_reports_nodes(cluster, local_run, tmp_path, capsys):
    import shutil

    from usdscene.cli import main

    out = tmp_path / "out"
    shutil.copytree(local_run, out)
    assert main(["render", str(out / "stage" / "scene.usda"), "-o", str(out), "--executor", "ray",
                 "--ray-address", cluster.address, "--no-progress"]) == 0
    assert "0 images rendered, 6 already done" in capsys.readouterr().out

    # A task no node can hold is refused with the resource named, before anything runs.
    code = main(["render", str(out / "stage" / "scene.usda"), "-o", str(tmp_path / "other"), "--frames", "0",
                 "--executor", "ray", "--ray-address", cluster.address, "--task-cpus", "4", "--no-progress"])
    assert code == 1
    assert "no node of the Ray cluster has 4 CPUs" in capsys.readouterr().err

    # An address nobody listens on fails at once with the address named (Ray would retry).
    code = main(["render", str(out / "stage" / "scene.usda"), "-o", str(tmp_path / "other"), "--frames", "0",
                 "--executor", "ray", "--ray-address", "127.0.0.1:1", "--no-progress"])
    assert code == 1
    assert "cannot reach Ray at '127.0.0.1:1'" in capsys.readouterr().err


def test_stage_bundle_mirrors_layers_and_assets(local_run, tmp_path):
    from pxr import Usd

    from usdscene.render.ray_executor import bundle_stage

    stage_path = local_run / "stage" / "scene.usda"
    bundle = bundle_stage(stage_path)
    assert bundle.stage == stage_path.resolve().as_posix().lstrip("/")
    assert any(name.endswith("assets/objects/laptop.usda") for name in bundle.files)
    extracted = bundle.extract(tmp_path / "node")
    stage = Usd.Stage.Open(str(extracted))
    # The extracted copy composes from the extracted assets, not from the originals.
    laptop = [p for p in stage.Traverse() if "laptop" in p.GetPath().pathString.lower()]
    assert laptop, "the laptop asset did not compose from the bundle"
    stack = [spec.layer.realPath for spec in laptop[0].GetPrimStack()]
    assert any(path.startswith(str(tmp_path / "node")) and "assets" in path for path in stack), stack


def test_a_ray_task_renders_with_the_shipped_hdri(cluster, tmp_path):
    """The world's HDRI travels in the stage bundle: the task renders with its copy although
    the original is gone from the driver's disk, and gives the local executor's bytes."""
    import json

    import cv2
    import numpy as np

    from usdscene.pipeline import RunOptions, compose_document, run_pipeline
    from usdscene.render.driver import render
    from usdscene.render.ray_executor import RayExecutor, bundle_stage
    from usdscene.render.stage_reader import stage_digest

    hdri = tmp_path / "sky.hdr"
    picture = np.zeros((8, 16, 3), np.float32)
    picture[:4] = (0.9, 0.6, 0.3)  # BGR: a blue upper hemisphere
    picture[4:] = (0.2, 0.2, 0.2)
    assert cv2.imwrite(str(hdri), picture)
    doc = json.loads(MINIMAL.read_text())
    block = doc["openlabel"]["metadata"]["usdscene"]
    block["world"] = {"hdri": "sky.hdr", "strength": 2.0}
    block["frame_range"] = {"frame_start": 0, "frame_end": 0}
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(doc))
    local = tmp_path / "local"
    run_pipeline(path, local, RunOptions(exports=[]), progress=False)

    out = tmp_path / "ray"
    compose_document(path, out / "stage")
    stage = out / "stage" / "scene.usda"
    bundle = bundle_stage(stage)
    assert bundle.hdri == hdri.resolve().as_posix().lstrip("/")
    assert bundle.files[bundle.hdri] == hdri.read_bytes()
    # The stage's digest covers the HDRI: an edited one invalidates finished images on resume.
    original = hdri.read_bytes()
    digest = stage_digest(stage)
    hdri.write_bytes(original[:-4] + b"\0\0\0\0")
    assert stage_digest(stage) != digest
    hdri.write_bytes(original)
    moved = []

    def hide_the_hdri(event: dict) -> None:
        if event.get("event") == "started" and not moved:  # the bundle is in the object store
            hdri.rename(tmp_path / "elsewhere.hdr")
            moved.append(True)

    report = render(stage, out, progress=False, on_event=hide_the_hdri, executor=RayExecutor(cluster.address))
    assert moved and not hdri.exists()
    assert report.pairs_rendered == 2
    for camera in ("cam_01", "cam_02"):
        for where in (layout.image_path, layout.mask_path):
            assert where(out, camera, 0).read_bytes() == where(local, camera, 0).read_bytes(), (camera, where)


def test_depth_through_ray_matches_the_local_executor_byte_for_byte(cluster, tmp_path):
    """Depth images rendered by Ray tasks on the cluster's nodes are the local executor's bytes,
    on the perspective camera and on the OpenCV fisheye (rendered native and remapped)."""
    import json

    from usdscene.pipeline import RunOptions, compose_document, run_pipeline
    from usdscene.render.depth import read_depth
    from usdscene.render.driver import render
    from usdscene.render.ray_executor import RayExecutor

    doc = json.loads(MINIMAL.read_text())
    doc["openlabel"]["metadata"]["usdscene"]["render"]["depth"] = "png16"
    path = tmp_path / "scene.openlabel.json"
    path.write_text(json.dumps(doc))
    local = tmp_path / "local"
    run_pipeline(path, local, RunOptions(exports=[]), progress=False)
    out = tmp_path / "ray"
    compose_document(path, out / "stage")
    report = render(out / "stage" / "scene.usda", out, progress=False,
                    executor=RayExecutor(cluster.address, max_slots=2))
    assert report.executor == "ray" and report.pairs_rendered == 6
    depths = sorted(p.relative_to(local) for p in local.glob("depth/*/*.png"))
    assert len(depths) == 6 and {p.parts[1] for p in depths} == {"cam_01", "cam_02"}
    for relative in depths:
        assert (out / relative).read_bytes() == (local / relative).read_bytes(), relative
        assert read_depth(local / relative).max() > 0, relative  # the cameras see surfaces
    for camera in ("cam_01", "cam_02"):
        for frame in range(3):
            for where in (layout.image_path, layout.mask_path):
                assert where(out, camera, frame).read_bytes() == where(local, camera, frame).read_bytes()
