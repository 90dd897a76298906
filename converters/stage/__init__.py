"""The USD stage route back to the document: any composed or DCC-edited stage ↔
:class:`usdscene.document.model.SceneSpec` (``usd_stage.scene_from_stage``)."""
