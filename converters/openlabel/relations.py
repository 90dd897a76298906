"""Relations of an OpenLABEL document (``is_on``, ``is_below``, ...). Pure module.

A relation links one subject to one object by uid. The placement relations of
:class:`usdscene.document.model.RelationType` put a dynamic object on a place or on another object; other
relation types are carried as they are. ``frames[f].relations`` markers must name existing
relations.
"""

from __future__ import annotations

import logging
from typing import Mapping

from usdscene.document.model import PLACEMENT_RELATIONS, FrameInterval, Relation

from usdscene.converters.openlabel.carry import relation_residue
from usdscene.converters.openlabel.load import DocumentBody
from usdscene.converters.openlabel.objects import UID_PATTERN
from usdscene.converters.openlabel.values import describe, read_intervals

log = logging.getLogger(__name__)



def read_relations(doc: DocumentBody, uids: Mapping[str, str]) -> list[Relation]:
    """``relations`` between objects, in document order.

    Args:
        doc: the document; problems are recorded in it.
        uids: uid → ``"light"``, ``"place"``, ``"object"`` or ``"other"`` of every object, as
            :func:`usdscene.converters.openlabel.objects.read_objects` returns it.

    Returns:
        Relations with one subject and one object; those involving actions, events or contexts
        are checked and read past (the scene model has no place for them).
    """
    R = doc.root
    others = {kind: doc.section(kind) for kind in ("actions", "events", "contexts")}
    relations = []
    for ruid, rel in doc.section("relations").items():
        where = f"{R}.relations.{ruid}"
        if not UID_PATTERN.match(ruid):
            doc.add(where, f"relation uid {ruid!r} must be an integer string or a UUID")
        if not isinstance(rel, dict):
            doc.add(where, f"expected a JSON object, got {describe(rel)}")
            continue
        rtype = rel.get("type")
        if not isinstance(rtype, str) or not rtype:
            doc.add(f"{where}.type", f"expected the relation type (e.g. 'is_below'), got {describe(rtype)}")
            continue
        agents, ok = _read_agents(doc, where, ruid, rel, uids, others)
        intervals: tuple[FrameInterval, ...] = ()
        if "frame_intervals" in rel:
            intervals = read_intervals(rel["frame_intervals"], f"{where}.frame_intervals", doc.problems) or ()
        if not ok:
            continue
        if any(kind != "object" for side in agents.values() for kind, _ in side):
            log.debug("%s: relation with actions/events/contexts is not modelled", where)
            continue
        if len(agents["rdf_subjects"]) != 1 or len(agents["rdf_objects"]) != 1:
            doc.add(where, f"relation {ruid} has {len(agents['rdf_subjects'])} subjects and "
                           f"{len(agents['rdf_objects'])} objects; usdscene relations have exactly one of each")
            continue
        subject, target = agents["rdf_subjects"][0][1], agents["rdf_objects"][0][1]
        if rtype in PLACEMENT_RELATIONS:
            if uids.get(subject) != "object":
                doc.add(f"{where}.rdf_subjects[0].uid",
                        f"{rtype} places a dynamic object, but {subject!r} is a {uids.get(subject)}")
                continue
            if uids.get(target) not in ("object", "place"):
                doc.add(f"{where}.rdf_objects[0].uid",
                        f"{rtype} needs a place or a dynamic object, but {target!r} is a {uids.get(target)}")
                continue
            if subject == target:
                doc.add(f"{where}.rdf_objects[0].uid", f"object {subject!r} cannot be {rtype} itself")
                continue
        relations.append(Relation(uid=ruid, type=rtype, subject_uid=subject, object_uid=target,
                                  frame_intervals=intervals, extra=relation_residue(rel)))
    return relations


def _read_agents(doc: DocumentBody, where: str, ruid: str, rel: Mapping, uids: Mapping[str, str],
                 others: Mapping[str, Mapping]) -> tuple[dict[str, list[tuple[str, str]]], bool]:
    """A relation's ``rdf_subjects`` and ``rdf_objects`` as ``side → [(kind, uid)]``, and
    whether every entry was good (each bad one is recorded in ``doc``); ``others``: the
    document's actions, events and contexts by section name."""
    agents = {}
    ok = True
    for side in ("rdf_subjects", "rdf_objects"):
        entries = rel.get(side)
        if not isinstance(entries, list) or not entries:
            doc.add(f"{where}.{side}", f"expected a non-empty list of {{'uid', 'type'}}, got {describe(entries)}")
            ok = False
            continue
        agents[side] = []
        for index, agent in enumerate(entries):
            here = f"{where}.{side}[{index}]"
            if not isinstance(agent, dict) or not isinstance(agent.get("uid"), str):
                doc.add(here, f"expected {{'uid': str, 'type': 'object'}}, got {describe(agent)}")
                ok = False
                continue
            kind = agent.get("type", "object")
            if kind not in ("object", "action", "event", "context"):
                doc.add(f"{here}.type", f"expected object, action, event or context, got {describe(kind)}")
                ok = False
                continue
            target = agent["uid"]
            exists = target in uids if kind == "object" else target in others[kind + "s"]
            if not exists:
                doc.add(f"{here}.uid", f"relation {ruid} refers to {kind} {target!r}, which does not exist")
                ok = False
                continue
            agents[side].append((kind, target))
    return agents, ok


def check_frame_relations(doc: DocumentBody) -> None:
    """``frames[f].relations[uid]`` markers must name existing relations."""
    known = doc.section("relations")
    for _, where, marks in doc.frame_sections("relations"):
        for uid in marks:
            if uid not in known:
                doc.add(f"{where}.{uid}", f"relation {uid!r} does not exist in {doc.root}.relations")
