"""The asset catalog: asset class → USD file, kind, variants, extents, places.

Pure module (json + numpy): validation and composition planning read the catalog without
importing pxr. The USD files stay the truth for geometry; ``catalog.json`` is written by the
same generator (or by ``usdscene assets add``) and mirrors what composition needs.

``catalog.json`` format (version 1)::

    {
      "format": "usdscene-catalog", "version": 1,
      "classes": {
        "backpack": {
          "kind": "object",                       # environment | object | passenger
          "usd": "objects/backpack.usda",         # relative to the catalog folder
          "description": "...",
          "variants": {"appearance": ["navy", "red"]},
          "default_variants": {"appearance": "navy"},
          "extent_m": [[-0.16, -0.11, 0.0], [0.16, 0.11, 0.45]],  # asset frame, Z up
          "relations": ["is_on", "is_below", "is_in", "is_in_front_of"],
          "places": {},                           # see Place
          "variant_places": {},                   # objects and passengers, see below
          "orientations": "any",                  # upright | upright_turned | any (default any)
          "variant_extents": {"appearance": {"navy": [[...], [...]]}},  # when variants differ
          "color_shader": "Looks/Body/Surface",   # shader a colour overrides; "" = none
          "forward_axis": "-Y"                    # the source file's front, recorded
        }
      }
    }

Asset frames: Z up, metres, origin at the centre of the bottom face of the object, so an
object rests on a surface when its origin lies on it.

``places`` of an environment are its named targets in world (= environment) coordinates. An
``object`` or ``passenger`` entry may declare *support places* of its own in the same form, in
object coordinates: where another object goes when it ``is_on`` (``is_in``, ...) an object of
this class (a passenger's ``lap``). Places that depend on a variant (the lap moves with the
passenger's ``pose``) go under ``variant_places``: variant set → variant → places, which
replace ``places`` when that variant is selected; a variant listed with no places (``{}``) has
none (a sleeping passenger's hands lie in its lap). At most one variant set carries places;
besides it, a combination of sets (``pose+appearance``: keys ``<pose>+<appearance>``) may
give the exact places of each combination, used when every set of it is selected explicitly.
"""

from __future__ import annotations

import dataclasses

import functools
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

from usdscene.document.model import Pose, SceneSpec
from usdscene.document.stage_schema import ASSET_COLOR_SHADER
from usdscene.errors import AssetError, ProblemCollector
from usdscene.shipped import default_asset_folder

CATALOG_FILE = "catalog.json"
ASSET_KINDS = ("environment", "object", "passenger")

ORIENTATION_RULES = ("upright", "upright_turned", "any")
"""How placement may lay an object of a class: ``upright`` only as modelled (yaw noise only),
``upright_turned`` also turned a quarter about its up axis, ``any`` also lying on a side when
it does not fit upright (luggage under a seat). A catalog entry without the key is ``any``."""

DEFAULT_COLOR_SHADER = ASSET_COLOR_SHADER
"""Where a scene's colour goes unless the entry names another shader (``color_shader``): the
library's ``Body`` material (:data:`usdscene.document.stage_schema.ASSET_COLOR_SHADER`)."""

# Place region prim names in environment assets and the placement relation each serves.
REGION_RELATIONS = {
    "on": "is_on",
    "below": "is_below",
    "in_front": "is_in_front_of",
    "back_pocket": "is_in",
    "in": "is_in",
}


@dataclass(frozen=True)
class PlaceRegion:
    """A box where a relation may put objects.

    The region frame has Z up; the support surface is its z = 0 plane; the usable volume is
    x ∈ [-size_m[0]/2, size_m[0]/2], y ∈ [-size_m[1]/2, size_m[1]/2], z ∈ [0, size_m[2]].

    Attributes:
        relation: the placement relation this region serves (``is_on``, ``is_below``, ...).
        pose: region frame → environment (= world) frame.
        size_m: (x, y, z) size of the usable box in metres.
    """

    relation: str
    pose: Pose
    size_m: tuple[float, float, float]


@dataclass(frozen=True)
class Place:
    """A named target inside an environment (``seat_03A``, ``bin_02L``, ``aisle_04``).

    Attributes:
        name: place name, unique in its environment.
        kind: ``seat``, ``bin``, ``aisle``, ...
        regions: relation name → region.
    """

    name: str
    kind: str
    regions: Mapping[str, PlaceRegion] = field(default_factory=dict)


@dataclass(frozen=True)
class AssetEntry:
    """One asset class of the catalog.

    Attributes:
        class_name: class name used as OpenLABEL object ``type``.
        kind: ``environment``, ``object`` or ``passenger``.
        usd_path: absolute path of the asset's USD file.
        description: free text.
        variants: variant set name → variant names.
        default_variants: variant set name → default variant.
        extent_min_m, extent_max_m: axis-aligned bounds in the asset frame (metres).
        relations: placement relations the class supports as a subject.
        places: place name → Place. Environments: their places (world coordinates). Objects
            and passengers: the support places they offer other objects (object coordinates)
            when no ``variant_places`` entry applies.
        variant_places: variant set → variant → the support places (object coordinates) of
            that variant, replacing ``places`` when it is selected (see :meth:`places_for`).
        orientations: placement rule, one of :data:`ORIENTATION_RULES`.
        variant_extents: variant set → variant → (min (3,), max (3,)) bounds in metres of that
            variant, for variants whose size or origin differ from the default's (``extent_*``
            is the default variant's); see :meth:`for_variants`.
        color_shader: prim path, relative to the asset's default prim, of the shader whose
            ``inputs:diffuseColor`` a scene's colour sets; ``""`` = the class is not recoloured.
        forward_axis: where the source file's front faced (Z up), before the import turned
            it to -Y; recorded for the reader.
    """

    class_name: str
    kind: str
    usd_path: Path
    description: str = ""
    variants: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    default_variants: Mapping[str, str] = field(default_factory=dict)
    extent_min_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    extent_max_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    relations: tuple[str, ...] = ()
    places: Mapping[str, Place] = field(default_factory=dict)
    variant_places: Mapping[str, Mapping[str, Mapping[str, Place]]] = field(default_factory=dict)
    orientations: str = "any"
    variant_extents: Mapping[str, Mapping[str, tuple[tuple[float, float, float], tuple[float, float, float]]]] = \
        field(default_factory=dict)
    color_shader: str = DEFAULT_COLOR_SHADER
    forward_axis: str = "-Y"

    def for_variants(self, selection: Mapping[str, str | None] | None = None) -> "AssetEntry":
        """This entry with the extent of the selected variants (``self`` when no selected
        variant has an extent of its own): what placement and the fit test use."""
        for set_name, by_variant in sorted(self.variant_extents.items()):
            chosen = (selection or {}).get(set_name) or self.default_variants.get(set_name)
            if chosen in by_variant:
                lo, hi = by_variant[chosen]
                if (tuple(lo), tuple(hi)) != (tuple(self.extent_min_m), tuple(self.extent_max_m)):
                    return dataclasses.replace(self, extent_min_m=tuple(lo), extent_max_m=tuple(hi),
                                               variant_extents={})
        return self

    @property
    def recolourable(self) -> bool:
        """Does a scene's colour reach a material of this class?"""
        return bool(self.color_shader)

    def places_for(self, selection: Mapping[str, str] | None = None) -> Mapping[str, Place]:
        """The places of this asset with the given variants selected.

        Args:
            selection: variant set → variant; sets it leaves out (or maps to None) take the
                entry's default variant.

        Returns:
            ``variant_places[set][variant]`` for the variant set that carries places when the
            selected variant is listed there, else ``places``.
        """
        chosen_of = dict(selection or {})
        for set_name, by_variant in sorted(self.variant_places.items()):
            if COMBINED_SETS in set_name:
                # A combination applies only when every one of its sets is chosen explicitly
                # (a seated body's lap depends on the body and the pose).
                names = [chosen_of.get(part) for part in set_name.split(COMBINED_SETS)]
                key = COMBINED_SETS.join(n for n in names if n)
                if all(names) and key in by_variant:
                    return by_variant[key]
        for set_name, by_variant in sorted(self.variant_places.items()):
            if COMBINED_SETS in set_name:
                continue
            chosen = chosen_of.get(set_name) or self.default_variants.get(set_name)
            if chosen in by_variant:
                return by_variant[chosen]
        return self.places

    def support_region(self, relation: str, selection: Mapping[str, str] | None = None) -> tuple[str, PlaceRegion] | None:
        """``(place name, region)`` that this asset offers an object related to it by
        ``relation`` with the given variants selected (the first such place by name), or None.
        """
        for name, place in place_items(self.places_for(selection)):
            if relation in place.regions:
                return name, place.regions[relation]
        return None

    def declares_support(self, relation: str) -> bool:
        """Does any variant of this asset declare a support place for ``relation``?"""
        every = [self.places, *(p for by in self.variant_places.values() for p in by.values())]
        return any(relation in place.regions for places in every for place in places.values())

    @property
    def size_m(self) -> tuple[float, float, float]:
        """Extent of the asset along x, y, z, metres."""
        return tuple(hi - lo for lo, hi in zip(self.extent_min_m, self.extent_max_m))  # type: ignore[return-value]

    @property
    def appearances(self) -> tuple[str, ...]:
        """The variants of the ``appearance`` variant set (empty when it has none)."""
        from usdscene.document.stage_schema import VARIANT_SET_APPEARANCE

        return tuple(self.variants.get(VARIANT_SET_APPEARANCE, ()))

    @property
    def default_appearance(self) -> str | None:
        """The appearance an object gets when nothing chooses one (None without variants)."""
        from usdscene.document.stage_schema import VARIANT_SET_APPEARANCE

        variants = self.appearances
        return self.default_variants.get(VARIANT_SET_APPEARANCE, variants[0]) if variants else None


@dataclass(frozen=True)
class Catalog:
    """All asset classes visible to a scene (shipped library + extra folders).

    Attributes:
        entries: class name → entry. A later folder overrides an earlier one.
        folders: the catalog folders that were read, in order.
        roots: resolved folders the assets' USD files and their composition arcs may lie in
            (:mod:`usdscene.document.containment`); empty means unchecked (a catalog built in code).
    """

    entries: Mapping[str, AssetEntry]
    folders: tuple[Path, ...] = ()
    roots: tuple[Path, ...] = ()

    def __contains__(self, class_name: str) -> bool:
        return class_name in self.entries

    def __getitem__(self, class_name: str) -> AssetEntry:
        return self.entries[class_name]

    def classes(self, kind: str | None = None) -> tuple[str, ...]:
        """Sorted class names, only those of ``kind`` when given."""
        return tuple(sorted(k for k, e in self.entries.items() if kind is None or e.kind == kind))

    def places(self, environment: str) -> Mapping[str, Place]:
        """Place name → place of environment ``environment``; raises KeyError for an unknown class."""
        return self.entries[environment].places


def load_catalog(extra_folders: Iterable[str | os.PathLike] = (), *,
                 include_default: bool = True, base_dir: str | os.PathLike | None = None,
                 consented: Iterable[str | os.PathLike] = ()) -> Catalog:
    """Read the shipped catalog plus extra catalog folders.

    With ``base_dir`` (the folder of the scene document that names ``extra_folders``), every
    folder must lie inside the reading roots of :func:`usdscene.document.containment.reading_roots`
    (the document's folder, the working folder, the shipped library, ``consented`` and
    ``$USDSCENE_ASSET_PATH``). Without it the caller vouches for ``extra_folders`` (folders
    given on the command line). Either way every entry's USD file must lie inside the roots or
    a catalog folder.

    Args:
        extra_folders: folders holding a ``catalog.json`` (relative ones resolved against
            ``base_dir``, e.g. the folder of the scene document).
        include_default: read the shipped library first.
        base_dir: folder that relative ``extra_folders`` are relative to (default: cwd, and
            the folders are then trusted).
        consented: more folders that may be read (``--asset-path``).

    Raises:
        AssetError: a folder or catalog file is missing, malformed or outside the reading
            roots, or an entry's USD file is outside them (all problems at once).
    """
    from usdscene.document.containment import is_inside, outside_problem, reading_roots

    folders: list[Path] = [default_asset_folder()] if include_default else []
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    problems = ProblemCollector()
    given = []
    for folder in extra_folders:
        p = Path(folder)
        given.append((folder, p if p.is_absolute() else base / p))
    roots = reading_roots(base_dir, consented if base_dir is not None else
                          [*consented, *(path for _, path in given)])
    for i, (folder, path) in enumerate(given):
        if base_dir is not None and not is_inside(path, roots):
            problems.extend([outside_problem(f"metadata.usdscene.asset_paths[{i}]", folder,
                                             "asset folder", anchor=base)])
        else:
            folders.append(path)
    roots = tuple(dict.fromkeys([*roots, *(f.resolve() for f in folders)]))
    entries: dict[str, AssetEntry] = {}
    for folder in folders:
        entries.update(_read_catalog_file(folder, problems, roots))
    problems.raise_if_any(AssetError)
    return Catalog(entries=entries, folders=tuple(folders), roots=roots)


def _read_catalog_file(folder: Path, problems: ProblemCollector,
                       roots: tuple[Path, ...]) -> dict[str, AssetEntry]:
    from usdscene.document.containment import is_inside, outside_problem

    path = folder / CATALOG_FILE
    try:
        stat = path.stat()
        parsed = _parsed_catalog(path, folder, stat.st_mtime_ns, stat.st_size)
    except FileNotFoundError:
        problems.add(str(path), "asset catalog not found (is this an asset folder?)")
        return {}
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        problems.add(str(path), f"cannot read asset catalog: {exc}")
        return {}
    if isinstance(parsed, str):
        problems.add(str(path), parsed)
        return {}
    entries = {}
    for name, usd, entry in parsed:
        where = f"{path}:classes.{name}"
        if isinstance(entry, str):
            problems.add(where, entry)
            continue
        if not is_inside(entry.usd_path, roots):
            problems.extend([outside_problem(where + ".usd", usd, "asset file", anchor=folder)])
            continue
        if entry.kind not in ASSET_KINDS:
            problems.add(where + ".kind", f"unknown kind {entry.kind!r}; expected one of {ASSET_KINDS}")
        entries[name] = entry
    return entries


@functools.lru_cache(maxsize=64)
def _parsed_catalog(path: Path, folder: Path, mtime_ns: int, size: int):
    """``catalog.json`` parsed into ``(name, usd as written, entry or problem text)`` per class,
    or one problem text for the whole file. Cached by modification time and size: validate,
    compose and export read the same (large) shipped catalog again and again.

    Raises:
        OSError, UnicodeDecodeError, json.JSONDecodeError: the file cannot be read.
    """
    data = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict) or not isinstance(data.get("classes"), dict):
        return "expected an object with a 'classes' object"
    parsed = []
    for name, raw in data["classes"].items():
        try:
            parsed.append((name, str(raw["usd"]), _entry_from_json(name, raw, folder)))
        except (KeyError, TypeError, ValueError) as exc:
            parsed.append((name, "", f"malformed catalog entry ({type(exc).__name__}: {exc})"))
    return tuple(parsed)


def _places_from_json(raw: Mapping) -> dict[str, Place]:
    """``places`` of a catalog entry (place name → {kind, regions}) read."""
    places = {}
    for pname, praw in raw.items():
        regions = {
            rel: PlaceRegion(relation=rel, pose=Pose.from_matrix(r["matrix"]),
                             size_m=tuple(float(v) for v in r["size_m"]))  # type: ignore[arg-type]
            for rel, r in praw.get("regions", {}).items()
        }
        places[pname] = Place(name=pname, kind=str(praw.get("kind", "")), regions=regions)
    return places


COMBINED_SETS = "+"
"""Joins variant-set names (and variant names) in a ``variant_places`` key that depends on
several sets: ``pose+appearance`` → ``upright+f_34_162_slim_tone2``."""


def _variant_places_from_json(raw: Mapping, variants: Mapping[str, tuple[str, ...]]) -> dict:
    """``variant_places`` read and checked against the entry's variant sets.

    Raises:
        ValueError: a variant set or variant the entry does not have, or places under more
            than one variant set (the message names the field and the value).
    """
    single = [name for name in raw if COMBINED_SETS not in name]
    if len(single) > 1:
        raise ValueError(f"variant_places: places under more than one variant set ({', '.join(sorted(single))}); "
                         "at most one variant set may carry places (plus combinations such as pose+appearance)")
    out = {}
    for set_name, by_variant in raw.items():
        parts = set_name.split(COMBINED_SETS)
        for part in parts:
            if part not in variants:
                raise ValueError(f"variant_places.{set_name}: the entry has no variant set {part!r} "
                                 f"(variant sets: {', '.join(sorted(variants)) or 'none'})")
        for variant in by_variant:
            names = variant.split(COMBINED_SETS)
            if len(names) != len(parts):
                raise ValueError(f"variant_places.{set_name}.{variant}: expected {len(parts)} variant names "
                                 f"joined by {COMBINED_SETS!r}")
            for part, name in zip(parts, names):
                if name not in variants[part]:
                    raise ValueError(f"variant_places.{set_name}.{variant}: {name!r} is not a variant of "
                                     f"{part!r} (variants: {', '.join(variants[part])})")
        out[set_name] = {variant: _places_from_json(places) for variant, places in by_variant.items()}
    return out


def _variant_extents_from_json(raw: Mapping, variants: Mapping[str, tuple[str, ...]]) -> dict:
    """``variant_extents`` read and checked against the entry's variant sets.

    Raises:
        ValueError: an unknown variant set or variant, or bounds that are not two triples.
    """
    out: dict = {}
    for set_name, by_variant in raw.items():
        for variant, bounds in by_variant.items():
            if variant not in variants.get(set_name, ()):
                raise ValueError(f"variant_extents.{set_name}.{variant}: not a variant of the entry")
            lo, hi = bounds
            if len(lo) != 3 or len(hi) != 3:
                raise ValueError(f"variant_extents.{set_name}.{variant}: expected [[x, y, z], [x, y, z]]")
            out.setdefault(set_name, {})[variant] = (tuple(float(v) for v in lo), tuple(float(v) for v in hi))
    return out


def entry_from_json(name: str, raw: Mapping, folder: Path) -> AssetEntry:
    """One catalog entry from its JSON form (paths relative to ``folder``); the inverse of
    :func:`entry_to_json`, without the reader's checks of the whole file."""
    return _entry_from_json(name, raw, folder)


def _entry_from_json(name: str, raw: Mapping, folder: Path) -> AssetEntry:
    lo, hi = raw.get("extent_m", [[0, 0, 0], [0, 0, 0]])
    variants = {k: tuple(v) for k, v in raw.get("variants", {}).items()}
    orientations = str(raw.get("orientations", "any"))
    if orientations not in ORIENTATION_RULES:
        raise ValueError(f"orientations: {orientations!r} is not one of {', '.join(ORIENTATION_RULES)}")
    return AssetEntry(
        class_name=name,
        kind=str(raw["kind"]),
        usd_path=(folder / raw["usd"]).resolve(),
        description=str(raw.get("description", "")),
        variants=variants,
        default_variants=dict(raw.get("default_variants", {})),
        extent_min_m=tuple(float(v) for v in lo),  # type: ignore[arg-type]
        extent_max_m=tuple(float(v) for v in hi),  # type: ignore[arg-type]
        relations=tuple(raw.get("relations", ())),
        places=_places_from_json(raw.get("places", {})),
        variant_places=_variant_places_from_json(raw.get("variant_places", {}), variants),
        orientations=orientations,
        variant_extents=_variant_extents_from_json(raw.get("variant_extents", {}), variants),
        color_shader=str(raw.get("color_shader", DEFAULT_COLOR_SHADER)),
        forward_axis=str(raw.get("forward_axis", "-Y")),
    )


def entry_to_json(entry: AssetEntry, folder: Path) -> dict:
    """Inverse of the reader for one entry; paths relative to ``folder``. Used by the
    generator and ``assets add``."""
    out: dict = {
        "kind": entry.kind,
        "usd": os.path.relpath(entry.usd_path, folder).replace(os.sep, "/"),
        "description": entry.description,
        "variants": {k: list(v) for k, v in entry.variants.items()},
        "default_variants": dict(entry.default_variants),
        "extent_m": [list(entry.extent_min_m), list(entry.extent_max_m)],
        "relations": list(entry.relations),
    }
    if entry.places:
        out["places"] = _places_to_json(entry.places)
    if entry.variant_places:
        out["variant_places"] = {set_name: {variant: _places_to_json(places) for variant, places in by_variant.items()}
                                 for set_name, by_variant in entry.variant_places.items()}
    # Only what differs from the defaults: catalogs written before these keys stay byte-identical.
    if entry.orientations != "any":
        out["orientations"] = entry.orientations
    if entry.variant_extents:
        out["variant_extents"] = {set_name: {v: [list(lo), list(hi)] for v, (lo, hi) in by_variant.items()}
                                  for set_name, by_variant in entry.variant_extents.items()}
    if entry.color_shader != DEFAULT_COLOR_SHADER:
        out["color_shader"] = entry.color_shader
    if entry.forward_axis != "-Y":
        out["forward_axis"] = entry.forward_axis
    return out


def _places_to_json(places: Mapping[str, Place]) -> dict:
    return {name: {"kind": place.kind,
                   "regions": {rel: {"matrix": list(r.pose.matrix), "size_m": list(r.size_m)}
                               for rel, r in place.regions.items()}}
            for name, place in place_items(places)}


def places_for_catalog(places: Mapping[str, tuple[str, Mapping[str, PlaceRegion]]]) -> dict[str, Place]:
    """The catalog form of authored places (place name → (kind, region prim name → region)):
    regions keyed by relation name."""
    return {name: Place(name=name, kind=kind,
                        regions={region.relation: region for _, region in sorted(regions.items())})
            for name, (kind, regions) in places.items()}


# The place's number: a last ``_``/``-`` part holding digits with up to two letters around
# them (``03``, ``03A``, ``A3``, ``B12``), or digits ending the name (``row12``).
_KIND_SUFFIX = re.compile(r"(?:[_-][A-Za-z]{0,2}[0-9]+[A-Za-z]{0,2}|[0-9]+[A-Za-z]?)$")


def place_kind(place: str) -> str:
    """Kind of a place from its name: the name without its number, letters of the number
    included (row or seat letters): ``bay_03``, ``bay_A3``, ``bay_B12`` → ``bay``,
    ``seat_03A`` → ``seat``, ``gate_12_bench_3`` → ``gate_12_bench``, ``row12`` → ``row``."""
    return _KIND_SUFFIX.sub("", place) or place


def place_items(places: Mapping[str, Place]) -> list[tuple[str, Place]]:
    """Places sorted by name (stable output order)."""
    return sorted(places.items())


def scene_catalog(catalog: Catalog, scene: SceneSpec) -> Catalog:
    """``catalog`` with the places the scene declares itself (regions of its place objects)
    merged into its environment's places. The placement module merges on entry (so compose
    and validation need not); code that reads ``catalog.places`` itself (the generator, camera
    design, ROI crops) calls this first. Returns ``catalog`` itself when the scene declares none or the
    environment is not in the catalog. A declared region replaces the asset's region of the
    same place and relation.
    """
    declared = [p for p in scene.places if p.regions]
    if not declared or scene.environment not in catalog:
        return catalog
    entry = catalog[scene.environment]
    places = dict(entry.places)
    for ref in declared:
        known = places.get(ref.name)
        regions = dict(known.regions) if known is not None else {}
        regions.update({r.relation: PlaceRegion(r.relation, r.pose, tuple(float(v) for v in r.size_m))
                        for r in ref.regions})
        places[ref.name] = Place(ref.name, known.kind if known is not None else place_kind(ref.name), regions)
    entries = dict(catalog.entries)
    entries[scene.environment] = dataclasses.replace(entry, places=places)
    return dataclasses.replace(catalog, entries=entries)
