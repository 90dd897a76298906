"""The scene document and its contracts: the SceneSpec model every format converts to and from,
the names of the composed stage, the output folder layout, the split rule a document may carry,
and which files a document or catalog may name. Pure (no pxr, no bpy); imports only the
foundation modules (errors, files, shipped, bulk, compiled)."""
