"""``usdscene export-openlabel STAGE -o DOC``: Scene2VCD, a USD stage or .blend → OpenLABEL;
``usdscene export-openlabel OUT -o DOC``: the labels of an annotated output folder (its
annotation store, :mod:`usdscene.converters.openlabel.store`) as one OpenLABEL document,
streamed frame by frame."""

from __future__ import annotations

import argparse

NAME = "export-openlabel"
HELP = ("read a USD stage (.usd/.usda/.usdc) or a .blend back into an OpenLABEL scene document, or write "
        "the labels of an annotated output folder as one OpenLABEL document")
ORDER = 60

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``usdscene export-openlabel`` arguments and options to ``parser``."""
    from usdscene.commands._arguments import output_path

    parser.add_argument("stage", metavar="STAGE",
                        help="composed or DCC-edited stage (file, or a stage folder with scene.usda), a .blend "
                             "file, or an annotated output folder (OUT with annotations/)")
    parser.add_argument("-o", "--out", type=output_path, metavar="DOC", required=True, help="OpenLABEL document to write (.json)")


def run(args: argparse.Namespace) -> int:
    """``usdscene export-openlabel``: write the OpenLABEL document of a USD stage or .blend; returns the
    exit status."""
    import importlib
    from pathlib import Path

    from rich.console import Console

    from usdscene.converters.openlabel import write_document, write_openlabel
    from usdscene.errors import DocumentError

    source = Path(args.stage)
    if source.is_dir():
        from usdscene.converters.openlabel.store import INDEX_FILE, AnnotationStore, store_folder

        if (store_folder(source) / INDEX_FILE).is_file():
            store = AnnotationStore(store_folder(source))
            written = store.write_document(args.out)
            index = store.index
            Console(highlight=False, soft_wrap=True).print(
                f"wrote {args.out}: {index['frames']} frames, {index['images']} images, {index['labels']} visible "
                f"labels from {store.folder}/ ({written['bytes'] / 1e6:.1f} MB)")
            return 0
    suffix = source.suffix.lower()
    if source.is_dir():  # a composed stage folder
        suffix = ".usda"
    if suffix in USD_SUFFIXES:
        from usdscene.converters.stage.usd_stage import scene_from_stage

        scene = scene_from_stage(source)
    elif suffix == ".blend":
        try:
            blend_io = importlib.import_module("usdscene.render.blend_io")
            scene_from_blend = blend_io.scene_from_blend
        except (ImportError, AttributeError):
            raise DocumentError("reading .blend files needs usdscene.render.blend_io.scene_from_blend, "
                                "which this installation lacks; export the scene to USD from Blender "
                                "and pass the .usd file instead", where=str(source)) from None
        scene = scene_from_blend(source)
    else:
        raise DocumentError(f"unsupported file type {suffix or '(none)'!r}; expected one of "
                            f"{', '.join(USD_SUFFIXES)} or .blend", where=str(source))
    write_document(Path(args.out), write_openlabel(scene))
    Console(highlight=False, soft_wrap=True).print(
        f"wrote {args.out}: {len(scene.cameras)} cameras, {len(scene.lights)} lights, "
        f"{len(scene.objects)} objects, frames {scene.frame_start}..{scene.frame_end}")
    return 0
