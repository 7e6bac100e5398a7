"""Repository functions of the registry: hands, signature versions, plans and jobs, under one name.

Every function opens its own short session on a :class:`~softsig_service.registry.db.Registry` and returns plain,
immutable records (never ORM objects), so callers in any thread can use the result after the session is closed.
Errors are :class:`~softsig_service.errors.SoftsigError` subclasses naming the field: :class:`HandNotFound`,
:class:`NotFound`, :class:`Conflict`, :class:`PreconditionFailed`.

The functions live by concern in :mod:`~softsig_service.registry.hands` (ETags, revisions),
:mod:`~softsig_service.registry.signatures` (gapless versions), :mod:`~softsig_service.registry.plans` and
:mod:`~softsig_service.registry.jobs`; this module gathers them for callers that write ``repo.add_plan(...)``.
"""

from __future__ import annotations

from softsig_service.registry.hands import (
    HandRecord,
    add_hand,
    delete_hand,
    etag_matches,
    get_hand,
    hand_names,
    list_hands,
    replace_hand,
    sync_builtin_hand,
)
from softsig_service.registry.jobs import (
    JOB_STATUSES,
    UNFINISHED,
    JobRecord,
    add_job,
    get_job,
    interrupt_unfinished_jobs,
    list_jobs,
    request_cancel,
    update_job,
)
from softsig_service.registry.plans import PlanRecord, add_plan, get_plan, list_plans
from softsig_service.registry.signatures import (
    SignatureRecord,
    add_signature,
    get_signature,
    latest_signature,
    list_signatures,
)

__all__ = [
    "JOB_STATUSES",
    "UNFINISHED",
    "HandRecord",
    "JobRecord",
    "PlanRecord",
    "SignatureRecord",
    "add_hand",
    "add_job",
    "add_plan",
    "add_signature",
    "delete_hand",
    "etag_matches",
    "get_hand",
    "get_job",
    "get_plan",
    "get_signature",
    "hand_names",
    "interrupt_unfinished_jobs",
    "latest_signature",
    "list_hands",
    "list_jobs",
    "list_plans",
    "list_signatures",
    "replace_hand",
    "request_cancel",
    "sync_builtin_hand",
    "update_job",
]
