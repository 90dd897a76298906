"""Shared bodies: the imported meshes that are equal share one Blender mesh (linked duplicates).

The stage references a person's asset once per pose it shows (``stage_schema.POSE_CHILD_PREFIX``
children), and Blender's USD importer makes a mesh datablock for every reference: a crowd of
500 walkers of one body family imports thousands of copies of a few (body, pose) meshes.
After the import, :func:`share_equal_meshes` keeps the first mesh of every group of equal ones
and points the other objects at it. Cycles then builds each shared mesh's geometry and BVH
once and instances it, so a render's memory and scene sync grow with the number of distinct
(body, pose) meshes, not with the number of people.

Masks stay exact: the object index (``pass_index``) is a property of the object, not of the
mesh. Each object keeps its own materials (its own colour opinion): its material slots are
linked to the object before its mesh is swapped. Meshes are equal when their vertex positions,
faces, face materials, UV layers, colour attributes and custom properties are equal (compared by
a hash of their bytes); meshes with shape keys, or of objects with modifiers, are left alone.
"""

from __future__ import annotations

import hashlib

import numpy as np


def _floats(collection, field: str, width: int) -> bytes:
    values = np.empty(len(collection) * width, dtype=np.float32)
    collection.foreach_get(field, values)
    return values.tobytes()


def _ints(collection, field: str) -> bytes:
    values = np.empty(len(collection), dtype=np.int32)
    collection.foreach_get(field, values)
    return values.tobytes()


def mesh_key(mesh) -> str:
    """A digest of everything of ``mesh`` (a ``bpy.types.Mesh``) that a render or a mask sees."""
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{len(mesh.vertices)} {len(mesh.polygons)} {len(mesh.loops)} {len(mesh.materials)}".encode())
    h.update(_floats(mesh.vertices, "co", 3))
    h.update(_ints(mesh.loops, "vertex_index"))
    h.update(_ints(mesh.polygons, "loop_start"))
    h.update(_ints(mesh.polygons, "material_index"))
    h.update(_ints(mesh.polygons, "use_smooth"))
    for layer in mesh.uv_layers:
        h.update(layer.name.encode())
        h.update(_floats(layer.data, "uv", 2))
    for attribute in mesh.color_attributes:
        h.update(f"{attribute.name} {attribute.domain} {attribute.data_type}".encode())
        h.update(_floats(attribute.data, "color", 4))
    h.update(repr(sorted((k, repr(mesh[k])) for k in mesh.keys())).encode())
    return h.hexdigest()


def share_equal_meshes(bpy, objects) -> tuple[int, int]:
    """Make the mesh objects of ``objects`` (iterable of ``bpy.types.Object``) with equal meshes
    (:func:`mesh_key`) use one mesh, each keeping its own materials; the copies are removed.

    Returns:
        ``(meshes before, meshes after)`` among those objects.
    """
    first: dict[str, object] = {}
    seen: set[str] = set()
    replaced = 0
    for ob in objects:
        mesh = ob.data
        if ob.type != "MESH" or mesh is None or mesh.name in seen or mesh.shape_keys is not None or len(ob.modifiers):
            continue
        key = mesh_key(mesh)
        shared = first.get(key)
        if shared is None:
            first[key] = mesh
            seen.add(mesh.name)
            continue
        materials = [slot.material for slot in ob.material_slots]
        ob.data = shared
        for slot, material in zip(ob.material_slots, materials):
            slot.link = "OBJECT"
            slot.material = material
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)
        replaced += 1
    return len(first) + replaced, len(first)
