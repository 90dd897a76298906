"""Blender projects: a .blend of a whole stage for camera design (``build_blend``), a .blend
exported to USD (``export_blend_usd``) and a .blend's cameras, presence and document read back
(``inspect_blend``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from usdscene.render.blender.camera import apply_intrinsics, camera_data_json
from usdscene.render.blender.process import emit, import_bpy
from usdscene.render.blender.session import Session, member_hides
from usdscene.render.job import BlendJob, BlendToUsdJob, InspectBlendJob


def build_blend(job: BlendJob) -> None:
    """Write a Blender project of the whole stage: every object (presence keyframed per frame,
    pass index = mask id), one Blender camera per stage camera (pose keyframed when it moves,
    exact intrinsics kept as custom properties), render settings as for rendering; the scene's
    document (``job.document``) as a custom property of the Blender scene."""
    from usdscene.document import stage_schema as ss
    from usdscene.render.job import intrinsics_to_json, usd_camera_matrix

    session = Session(job)
    import mathutils  # importable only once bpy is
    bpy, scene = session.bpy, session.scene
    bpy.data.objects.remove(session.camera, do_unlink=True)
    frames = range(int(job.frame_start), int(job.frame_end) + 1)
    scene.frame_start, scene.frame_end = frames[0], frames[-1]
    if job.document:
        scene[ss.BLEND_DOCUMENT] = job.document
    for o in job.objects:
        members = session.objects.get(o.uid, [])
        poses = session.poses.get(o.uid)
        hides = [dict((ob.name, h) for ob, h in member_hides(o, members, poses or {}, f)) for f in frames]
        for ob in members:
            previous = None
            for f, hidden in zip(frames, hides):
                hide = hidden[ob.name]
                if hide != previous:
                    # Render visibility only: an object hidden in the viewport leaves the
                    # depsgraph and its matrix goes stale (the USD exporter would write it).
                    ob.hide_render = hide
                    ob.keyframe_insert("hide_render", frame=f)
                    previous = hide
    collection = bpy.data.collections.new("Cameras")
    scene.collection.children.link(collection)
    first = None
    for name, cam_job in job.cameras.items():
        data = bpy.data.cameras.new(name)
        ob = bpy.data.objects.new(name, data)
        collection.objects.link(ob)
        render = cam_job.render_intrinsics
        apply_intrinsics(scene, data, render)
        data.clip_start, data.clip_end = cam_job.clip_m
        ob[ss.BLEND_CAMERA_NAME] = name
        ob["usdscene_lens"] = json.dumps(intrinsics_to_json(cam_job.intrinsics))
        ob["usdscene_render_lens"] = json.dumps(intrinsics_to_json(render))
        ob["usdscene_blender_lens"] = json.dumps(camera_data_json(data))
        ob.rotation_mode = "QUATERNION"
        ob.matrix_world = mathutils.Matrix(usd_camera_matrix(cam_job.pose))
        for f, pose in sorted(cam_job.poses.items()):
            ob.matrix_world = mathutils.Matrix(usd_camera_matrix(pose))
            ob.keyframe_insert("location", frame=int(f))
            ob.keyframe_insert("rotation_quaternion", frame=int(f))
        first = first or (ob, render)
    if first is not None:
        scene.camera = first[0]
        apply_intrinsics(scene, first[0].data, first[1])
    scene.frame_set(frames[0])
    out = Path(job.blend)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp), relative_remap=True)
    os.replace(tmp, out)
    emit({"event": "blend_written", "path": str(out)})


def export_blend_usd(job: BlendToUsdJob) -> None:
    """Export a .blend to a USD file (``job.usd``): Z up, metres, custom properties as
    ``userProperties:*`` (where place markers keep their ``usdscene_place``), default prim
    ``/root``; for ``usdscene assets add FILE.blend``."""
    bpy = import_bpy()
    bpy.ops.wm.open_mainfile(filepath=job.blend)
    result = bpy.ops.wm.usd_export(filepath=job.usd, export_custom_properties=True, export_materials=True,
                                   export_cameras=False, export_lights=False, convert_orientation=False,
                                   root_prim_path="/root", check_existing=False)
    if "FINISHED" not in result:
        raise RuntimeError(f"USD export of {job.blend} failed: {result}")
    emit({"event": "exported"})


def inspect_blend(job: InspectBlendJob) -> None:
    """Export a .blend to USD and dump its cameras (pose per frame, lens data, custom
    properties), the presence and matrices of its usdscene objects and the scene's document
    (custom property ``stage_schema.BLEND_DOCUMENT``, null when absent) as JSON: Blender's USD
    exporter writes only perspective cameras, and no customData or customLayerData."""
    from usdscene.document import stage_schema as ss

    bpy = import_bpy()
    bpy.ops.wm.open_mainfile(filepath=job.blend)
    scene = bpy.context.scene
    result = bpy.ops.wm.usd_export(filepath=job.usd, export_animation=True, export_cameras=True,
                                   export_custom_properties=True, export_materials=True,
                                   root_prim_path="", convert_orientation=False, check_existing=False)
    if "FINISHED" not in result:
        raise RuntimeError(f"USD export of {job.blend} failed: {result}")
    document = scene.get(ss.BLEND_DOCUMENT)
    frames = range(scene.frame_start, scene.frame_end + 1)
    cameras = {ob.name: {"data": camera_data_json(ob.data), "poses": {},
                         "custom": {k: ob[k] for k in ob.keys() if k.startswith("usdscene_")},
                         "clip_m": [ob.data.clip_start, ob.data.clip_end]}
               for ob in scene.objects if ob.type == "CAMERA"}
    presence: dict[str, list[int]] = {}
    matrices: dict[str, dict[str, list]] = {}
    tagged = []
    for ob in scene.objects:
        uid = ob.get("usdscene_uid")
        if uid is None and ob.data is not None and hasattr(ob.data, "get"):
            uid = ob.data.get("usdscene_uid")
        if uid is not None:
            tagged.append((str(uid), ob))
            presence.setdefault(str(uid), [])
    # Parents before children, so the object's root carries its pose.
    tagged.sort(key=lambda item: len(_ancestors(item[1])))
    for f in frames:
        scene.frame_set(f)
        for ob in scene.objects:
            if ob.type == "CAMERA":
                cameras[ob.name]["poses"][str(f)] = [list(row) for row in ob.matrix_world]
        for uid, ob in tagged:
            if not ob.hide_render and (not presence[uid] or presence[uid][-1] != f):
                presence[uid].append(f)
            if uid not in matrices.setdefault(str(f), {}):  # the outermost tagged object wins
                matrices[str(f)][uid] = [list(row) for row in ob.matrix_world]
    Path(job.json).write_text(json.dumps({
        "presence": presence,
        "object_matrices": matrices,
        "frame_start": scene.frame_start, "frame_end": scene.frame_end,
        "resolution_px": [scene.render.resolution_x, scene.render.resolution_y],
        "cameras": cameras,
        # Text as saved; anything else (a user's group property) reads back as malformed.
        "document": None if document is None else str(document)}))
    emit({"event": "inspected"})


def _ancestors(ob) -> list:
    out = []
    while ob.parent is not None:
        ob = ob.parent
        out.append(ob)
    return out
