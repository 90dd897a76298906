"""The Blender worker process's entry point; the work is done in :mod:`usdscene.render.blender`
(the only package of usdscene that imports ``bpy``).

Run as ``python -m usdscene.render.worker JOB.json`` (or with ``--wait-for-job``: import bpy
first, then read the job file's path from stdin, for a worker started before its job exists,
see :func:`usdscene.render.worker_process.prestart_workers`); never imported by the parent (bpy breaks
``multiprocessing`` and owns process-wide state). The job file (a
:class:`usdscene.render.job.RenderJob` written by the executor) says which stage to import,
which prims the shard needs, which objects are visible on which frames with which mask ids, the
calibrated cameras and their poses per frame, the render settings and the (frame, camera)
pairs to render, in order.

What happens:

1. Factory-empty scene; a black world is created *before* the USD import so that a dome light
   of the stage can replace it (the importer drops dome lights without a world).
2. ``wm.usd_import`` once, of the prims the shard needs only (``prim_path_mask``), instances
   realised (instanced prims would share the prototype's pass index), no cameras (one render
   camera of our own is driven from the job; switching ``scene.camera`` forces a full re-sync
   with persistent data).
3. Per frame: ``scene.frame_set`` (transform caches follow the stage's time samples), then
   ``hide_render`` for objects absent on that frame and ``pass_index`` = mask id.
4. Per camera: the render camera takes the camera's pose and intrinsics; Cycles renders a
   multilayer EXR on ``/dev/shm`` holding the beauty and the object-index pass of the *same*
   render; the worker converts the linear beauty to an 8-bit sRGB PNG and the object index to a
   uint16 PNG, remaps both with one shared map for OpenCV lens models (bilinear for the image,
   nearest for the mask), and writes them atomically.
5. After each pair a line ``@usdscene {json}`` goes to stdout (the driver parses those and
   ignores Blender's own chatter).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from usdscene.errors import RenderError
from usdscene.render.blender.blend import build_blend, export_blend_usd, inspect_blend
from usdscene.render.blender.cycles import DeviceError
from usdscene.render.blender.process import die_with_parent, emit, import_bpy
from usdscene.render.blender.session import Session, render_pairs
from usdscene.render.blender.world import bake_world
from usdscene.render.job import BakeWorldJob, BlendJob, BlendToUsdJob, InspectBlendJob, RenderJob, from_json


def main(argv: list[str] | None = None) -> int:
    """Entry point of the Blender worker process (``JOB.json`` or ``--wait-for-job``); returns the exit
    status (2 bad usage, 1 on a reported error)."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        sys.stderr.write("usage: python -m usdscene.render.worker JOB.json | --wait-for-job\n")
        return 2
    if argv[0] == "--wait-for-job":  # pre-started (worker_process.prestart_workers): bpy first
        import_bpy()
        job_path = sys.stdin.readline().strip()
        if not job_path:  # not needed after all
            return 0
        argv = [job_path]
    try:
        job = from_json(Path(argv[0]).read_text(), where=argv[0])
    except RenderError as exc:  # a job file of another version: one line for the driver
        emit({"event": "error", "message": str(exc)})
        return 1
    die_with_parent(job.parent_pid)
    if not isinstance(job, RenderJob):
        try:
            {BlendJob: build_blend, InspectBlendJob: inspect_blend, BlendToUsdJob: export_blend_usd,
             BakeWorldJob: bake_world}[type(job)](job)
        except Exception as exc:
            emit({"event": "error", "message": f"{type(exc).__name__}: {exc}"})
            return 1
        return 0
    try:
        session = Session(job)
    except Exception as exc:  # reported to the driver as one line, then exit non-zero
        # a missing GPU is the user's setting, not a crash: its message stands alone
        message = str(exc) if isinstance(exc, DeviceError) else f"{type(exc).__name__}: {exc}"
        emit({"event": "error", "message": message})
        return 1
    if not render_pairs(session, job.pairs):
        return 1
    try:
        session.exr_path.unlink()
    except FileNotFoundError:
        pass
    emit({"event": "finished", "process_cpu_s": time.process_time()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
