"""A yes/no collision verdict for one selection of pairs, in one C++ call per configuration (Pinocchio + coal).

Pinocchio's ``BroadPhaseManager`` holds every geometry of a world as a coal collision object with a world-frame
axis-aligned box. One call of ``pinocchio.computeCollisions(model, data, manager, q, stop_at_first)`` runs the
forward kinematics, moves the geometries and their boxes, and hands the pairs whose boxes overlap and that are
active in its ``GeometryData`` to coal. Each geometry's box is grown by half the largest (security margin +
break distance) of its active pairs, so a pair within its margin is never culled. Of coal's managers the
plain one (every two boxes compared, about a thousand box tests for the UR5 with a hand of some 40 shapes) is
the fastest here: about 6 µs per configuration against 12-33 µs for the tree, interval and sweep-and-prune
managers, which spend more on keeping their structure than they save on ~50 objects
(``benchmarks/bench_planner.py`` shows the check in a plan's split).

A :class:`PairManager` serves one selection of a world's pairs (those a set of check flags selects): it owns a
``GeometryData`` in which exactly those pairs are active, with the same collision requests as the world's, and
the manager built on it. Where it finds a collision, the caller asks the pairs one by one for the report; where
it finds none, nothing collides. It holds mutable state: one per world and thread, like the world.

Frames and units: world = UR5 ``base_link`` (z up); lengths in [m]; joint positions in [rad].
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from softsig_service.arm.shapes import local_aabb

FloatArray = NDArray[np.float64]

_Manager = pin.BroadPhaseManager_NaiveCollisionManager


def configure_requests(gd: pin.GeometryData) -> None:
    """The collision requests every world uses (``gd``'s, in place).

    coal 3.0.3 without contact computation can report "free" when a capsule's core segment just touches a box
    face (seen: a capsule 1 cm deep in a box, about 1 in 4000 random capsule/box poses). Asking for one contact
    runs EPA on overlap and gets these right.
    """
    for req in gd.collisionRequests:
        req.enable_contact = True
        req.num_max_contacts = 1


class PairManager:
    """Collision verdicts of the pairs ``active`` (indices into ``gm.collisionPairs``) at joint configurations.

    Args:
        model: the arm's Pinocchio model (the geometries' parent joints).
        gm: the world's geometry model.
        active: the pair indices to check.
        category_of: each active pair's margin category (``"table"``, ``"object"`` or ``"self"``).

    Raises ``ValueError`` when a geometry of an active pair has an empty bounding box (Pinocchio's manager
    silently leaves such a geometry out, so its pairs would never be asked); a world asks its pairs one by one
    then.
    """

    def __init__(
        self, model: pin.Model, gm: pin.GeometryModel, active: Iterable[int], category_of: Mapping[int, str]
    ) -> None:
        self._model = model
        self.gd = pin.GeometryData(gm)
        configure_requests(self.gd)
        self.gd.deactivateAllCollisionPairs()
        self._active = list(active)
        for k in self._active:
            self.gd.activateCollisionPair(k)
        self._category = [category_of[k] for k in self._active]
        for k in self._active:
            pair = gm.collisionPairs[k]
            for index in (pair.first, pair.second):
                if not local_aabb(gm.geometryObjects[index].geometry).aabb_local.volume() > 0.0:
                    raise ValueError(f"geometry {index} of pair {k} has an empty bounding box")
        self._manager = _Manager(model, gm, self.gd)
        self._margins: dict[str, float] = {}

    def set_margins(self, margins: Mapping[str, float]) -> None:
        """Security margins [m] by category (``"table"``, ``"object"``, ``"self"``) of the active pairs."""
        if dict(margins) == self._margins:
            return
        reqs = self.gd.collisionRequests
        for k, cat in zip(self._active, self._category, strict=True):
            reqs[k].security_margin = margins[cat]
        self._margins = dict(margins)

    def collides(self, data: pin.Data, q: FloatArray) -> bool:
        """Whether any active pair is within its margin at ``q`` ``(nq,)`` [rad] (``data`` is left at ``q``)."""
        return bool(pin.computeCollisions(self._model, data, self._manager, np.asarray(q, dtype=np.float64), True))
