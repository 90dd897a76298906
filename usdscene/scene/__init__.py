"""The scene: the asset catalog and its places, placement of objects by relations, and
composition of a SceneSpec into a layered USD stage (plus geometry read back from a stage).
Imports the document package and the foundation; nothing of labels, rendering or datasets."""
