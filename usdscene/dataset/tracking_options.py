"""The tracking exports' options resolved against one annotated document and its catalog:
which classes are people and vehicles for MOTChallenge's class column, and the user's mapping
checked before anything is written (:func:`usdscene.dataset.export.export_formats`)."""

from __future__ import annotations

from typing import Sequence


def mot_classes(document: dict, catalog, class_map: Sequence[str] = (), static_people: bool = False):
    """The :class:`usdscene.converters.exports.mot.MotClasses` of a document.

    People and vehicles are the catalog's person and vehicle classes
    (:func:`usdscene.generate.motion.person_classes`, :func:`~usdscene.generate.motion.vehicle_classes`);
    without a catalog only ``class_map`` names MOT classes.

    Args:
        document: the annotated document.
        catalog: its asset catalog, or None.
        class_map: ``CLASS=NUMBER`` items (:func:`usdscene.converters.exports.mot.parse_class_map`);
            a class is known when the catalog has it or the document has an object of it.
        static_people: people standing still get MOT's class 7.

    Raises:
        OutputError: a mapping item naming an unknown class or no MOT class.
    """
    from usdscene.converters.exports.mot import MotClasses, parse_class_map

    known = {(o or {}).get("type") for o in (document["openlabel"].get("objects", {}) or {}).values()} - {None}
    people: tuple[str, ...] = ()
    vehicles: tuple[str, ...] = ()
    if catalog is not None:
        from usdscene.generate.motion import person_classes, vehicle_classes

        people, vehicles = person_classes(catalog), vehicle_classes(catalog)
        known |= set(catalog.classes())
    return MotClasses(people=people, vehicles=vehicles, class_map=parse_class_map(class_map, known),
                      static_people=static_people)
