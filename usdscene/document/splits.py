"""Training splits: which images of a dataset are ``train``, ``val`` or ``test``. Pure (numpy).

A dataset is a list of images, each named by ``ImageKey(source, frame, camera)``: ``source``
is the output folder (one sequence document) it was rendered into. A :class:`SplitRule`
assigns every image to at most one split, deterministically:

``train=0.8,val=0.1,test=0.1`` (seeded fractions)
    Images are grouped by ``(source, frame)``, so the cameras of one moment never land in two
    splits (they see the same objects in the same places). The groups are sorted, shuffled by
    ``numpy.random.default_rng(seed)`` and cut at the rounded cumulative fractions; the
    fractions must add up to 1.
``frames:train=0:399,val=400:449,test=450:499`` (closed frame ranges, several joined by ``+``:
``train=0:99+200:299``)
``cameras:val=cam_01+cam_02,test=cam_03`` (camera names)
``documents:val=out_b,test=out_c`` (the source's folder name, or the output folder as given)

For the three listing rules, images that no entry names go to ``train`` when ``train`` is not
listed (``cameras:val=cam_03`` = cam_03 for validation, every other camera for training);
when ``train`` is listed too, images that no entry names are left out of every split (a gap
of frames between train and val is common practice against near-duplicate leakage). A frame,
camera or document named by two entries is an error, and so is a name that is not in the
dataset (a typo would silently put nothing in a split).

Split names are free words (letters, digits, ``_``, ``-``); they become file names
(``annotations_<split>.json``, ``<split>.txt``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, Mapping, NamedTuple

import numpy as np

from usdscene.errors import DocumentError, Problem, ProblemCollector

KINDS = ("fractions", "frames", "cameras", "documents")
"""Kinds of split rule; ``fractions`` is the one written without a ``kind:`` prefix."""

WHERE = "--split"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
_RANGE = re.compile(r"^\s*(-?\d+)\s*(?::\s*(-?\d+)\s*)?$")


class ImageKey(NamedTuple):
    """One image of a dataset: output folder label, frame number, camera name."""

    source: str
    frame: int
    camera: str


@dataclass(frozen=True)
class SplitRule:
    """A parsed ``--split`` rule.

    Attributes:
        kind: one of :data:`KINDS`.
        entries: split name → its value, in the order written: a fraction (float) for
            ``fractions``, closed ``(first, last)`` frame ranges for ``frames``, names for
            ``cameras`` and ``documents``.
        text: the rule as written (for messages and the split manifest).
    """

    kind: str
    entries: Mapping[str, object]
    text: str

    @property
    def names(self) -> tuple[str, ...]:
        """The split names in written order, plus ``train`` first when a listing rule leaves
        the rest to it."""
        listed = tuple(self.entries)
        if self.kind != "fractions" and "train" not in listed:
            return ("train", *listed)
        return listed


def parse_split(text: str, where: str = WHERE) -> SplitRule:
    """Parse a split rule (syntax in the module docstring).

    Args:
        text: the rule.
        where: what the problems name (``--split``, or the document field that holds it).

    Raises:
        DocumentError: naming ``where`` and the bad part of the text.
    """
    try:
        return _parse_split(text)
    except DocumentError as exc:
        if where == WHERE:
            raise
        raise DocumentError([Problem(where, p.message) for p in exc.problems]) from None


DOCUMENT_FIELD = "metadata.usdscene.split"
"""Where a scene document carries its split rule: ``{"rule": RULE, "seed": N}`` (seed
optional, default 0)."""


def document_split(document: Mapping) -> tuple[SplitRule, int] | None:
    """The split rule an OpenLABEL document carries (:data:`DOCUMENT_FIELD`), with its seed;
    None when it carries none.

    Raises:
        DocumentError: a malformed rule or seed, naming the field and the value.
    """
    meta = document.get("openlabel", document).get("metadata", {})
    block = meta.get("usdscene", {}) if isinstance(meta, Mapping) else {}
    value = block.get("split") if isinstance(block, Mapping) else None
    if value is None:
        return None
    problems = ProblemCollector()
    rule, seed = read_document_split(value, DOCUMENT_FIELD, problems)
    problems.raise_if_any(DocumentError)
    return (rule, seed) if rule is not None else None


def read_document_split(value, where: str, problems: ProblemCollector) -> tuple[SplitRule | None, int]:
    """Read ``{"rule": RULE, "seed": N}`` found at ``where``; problems go to ``problems``.

    Returns:
        (rule or None when it is bad, seed).
    """
    if not isinstance(value, Mapping):
        problems.add(where, f"expected an object {{\"rule\": RULE, \"seed\": N}}, got {value!r}")
        return None, 0
    for key in value:
        if key not in ("rule", "seed"):
            problems.add(f"{where}.{key}", f"unknown key {key!r}; known keys: rule, seed")
    seed = value.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        problems.add(f"{where}.seed", f"expected a non-negative integer, got {seed!r}")
        seed = 0
    text = value.get("rule")
    if not isinstance(text, str) or not text.strip():
        problems.add(f"{where}.rule", f"expected a split rule such as 'train=0.8,val=0.2', got {text!r}")
        return None, seed
    try:
        return parse_split(text, where=f"{where}.rule"), seed
    except DocumentError as exc:
        problems.extend(exc.problems)
        return None, seed


def _parse_split(text: str) -> SplitRule:
    problems = ProblemCollector()
    body = text.strip()
    kind = "fractions"
    head, sep, rest = body.partition(":")
    if sep and "=" not in head:
        kind, body = head.strip(), rest
        if kind not in KINDS[1:]:
            raise DocumentError([Problem(WHERE, f"unknown rule kind {kind!r} in {text!r}; expected "
                                                f"{', '.join(KINDS[1:])} or fractions without a prefix")])
    entries: dict[str, object] = {}
    for part in (p.strip() for p in body.split(",")):
        if not part:
            continue
        name, eq, value = (s.strip() for s in part.partition("="))
        if not eq:
            # ``cameras:val=a,b``: a bare word continues the previous entry's list of names
            if kind in ("cameras", "documents") and entries and _NAME.match(name):
                entries[next(reversed(entries))] += (name,)
                continue
            problems.add(WHERE, f"{part!r} in {text!r} is not SPLIT=VALUE")
            continue
        if not _NAME.match(name):
            problems.add(WHERE, f"split name {name!r} in {text!r} is not a word (letters, digits, _ or -)")
            continue
        if name in entries:
            problems.add(WHERE, f"split {name!r} is given twice in {text!r}")
            continue
        entries[name] = _parse_value(kind, name, value, text, problems)
    if not entries and not problems:
        problems.add(WHERE, f"{text!r} names no split")
    if kind == "fractions" and not problems:
        total = sum(entries.values())
        if abs(total - 1.0) > 1e-6:
            problems.add(WHERE, f"fractions in {text!r} add up to {total:g}, not 1")
    if kind == "frames" and not problems:
        _check_frame_overlaps(entries, text, problems)
    if kind in ("cameras", "documents") and not problems:
        seen: dict[str, str] = {}
        for split, names in entries.items():
            for item in names:
                if item in seen:
                    problems.add(WHERE, f"{kind[:-1]} {item!r} is in split {seen[item]!r} and {split!r}")
                seen.setdefault(item, split)
    problems.raise_if_any(DocumentError)
    return SplitRule(kind, entries, text.strip())


def _parse_value(kind: str, name: str, value: str, text: str, problems: ProblemCollector):
    if kind == "fractions":
        try:
            fraction = float(value)
        except ValueError:
            fraction = -1.0
        if not 0.0 <= fraction <= 1.0:
            problems.add(WHERE, f"fraction {value!r} of split {name!r} is not a number in [0, 1]")
        return fraction
    if kind == "frames":
        ranges = []
        for piece in value.split("+"):
            match = _RANGE.match(piece)
            if not match:
                problems.add(WHERE, f"frames {piece!r} of split {name!r} are not FIRST:LAST or N")
                continue
            first = int(match.group(1))
            last = int(match.group(2)) if match.group(2) is not None else first
            if last < first:
                problems.add(WHERE, f"frames {piece!r} of split {name!r}: {last} is before {first}")
                continue
            ranges.append((first, last))
        return tuple(ranges)
    names = tuple(v.strip() for v in value.split("+") if v.strip())
    if not names:
        problems.add(WHERE, f"split {name!r} in {text!r} names no {kind[:-1]}")
    return names


def _check_frame_overlaps(entries: Mapping[str, object], text: str, problems: ProblemCollector) -> None:
    spans = sorted((first, last, split) for split, ranges in entries.items() for first, last in ranges)
    for (a0, a1, sa), (b0, b1, sb) in zip(spans, spans[1:]):
        if b0 <= a1:
            problems.add(WHERE, f"frames {a0}:{a1} ({sa}) and {b0}:{b1} ({sb}) overlap in {text!r}")


def assign_splits(images: Iterable[ImageKey], rule: SplitRule, seed: int = 0, *,
                  source_aliases: Mapping[str, Iterable[str]] | None = None) -> dict[ImageKey, str]:
    """Split of every image; images that the rule leaves out are absent from the result.

    Args:
        images: the dataset's images (any order; the result does not depend on it).
        rule: from :func:`parse_split`.
        seed: seeds the shuffle of ``fractions`` rules (other kinds ignore it).
        source_aliases: for ``documents`` rules, extra names by which each source may be named
            (e.g. the output folder as typed on the command line).

    Returns:
        image → split name, in sorted image order.

    Raises:
        DocumentError: a ``cameras`` or ``documents`` rule names something not in the dataset.
    """
    keys = sorted(set(images))
    if rule.kind == "fractions":
        return _assign_fractions(keys, rule, seed)
    if rule.kind == "frames":
        def split_of(key: ImageKey) -> str | None:
            for split, ranges in rule.entries.items():
                if any(first <= key.frame <= last for first, last in ranges):
                    return split
            return None
    else:
        field = "camera" if rule.kind == "cameras" else "source"
        names = {}
        for key in keys:
            value = getattr(key, field)
            names[value] = value
            for alias in (source_aliases or {}).get(value, ()) if field == "source" else ():
                names[str(alias)] = value
        problems = ProblemCollector()
        owner = {}
        for split, items in rule.entries.items():
            for item in items:
                if item not in names:
                    problems.add(WHERE, f"{rule.kind[:-1]} {item!r} of split {split!r} is not in the dataset; "
                                        f"it has {sorted(set(names.values()))}")
                else:
                    owner[names[item]] = split
        problems.raise_if_any(DocumentError)

        def split_of(key: ImageKey) -> str | None:
            return owner.get(getattr(key, field))

    rest = None if "train" in rule.entries else "train"
    result = {}
    for key in keys:
        split = split_of(key) or rest
        if split is not None:
            result[key] = split
    return result


def _assign_fractions(keys: list[ImageKey], rule: SplitRule, seed: int) -> dict[ImageKey, str]:
    groups = sorted({(key.source, key.frame) for key in keys})
    order = np.random.default_rng(seed).permutation(len(groups))
    fractions = np.array(list(rule.entries.values()), dtype=np.float64)
    # Cut points at the rounded cumulative fractions: the counts differ from n * fraction by
    # less than one group and always add up to n.
    cuts = np.rint(np.cumsum(fractions) * len(groups)).astype(int)
    cuts[-1] = len(groups)
    group_split = {}
    start = 0
    for split, stop in zip(rule.entries, cuts):
        for index in order[start:stop]:
            group_split[groups[index]] = split
        start = max(start, stop)
    return {key: group_split[(key.source, key.frame)] for key in keys}


def split_counts(assignment: Mapping[ImageKey, str], names: Iterable[str]) -> dict[str, dict[str, int]]:
    """Images and (source, frame) groups per split: ``{split: {"images": n, "frames": m}}``."""
    counts = {}
    for name in names:
        keys = [k for k, s in assignment.items() if s == name]
        counts[name] = {"images": len(keys), "frames": len({(k.source, k.frame) for k in keys})}
    return counts
