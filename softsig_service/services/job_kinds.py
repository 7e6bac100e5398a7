"""The kinds of jobs the service runs, the work the API and the CLI share: stiffness signatures and capture models
(stored as a new signature version when the job succeeds), validations in MuJoCo and the reference experiment.
"""

from __future__ import annotations

from typing import Any

from softsig_service import registry as repo
from softsig_service.config import Settings
from softsig_service.hands.model import builtin_hand_names
from softsig_service.registry.db import Registry
from softsig_service.services.jobs import JobKind
from softsig_service.services.tasks import inspect_hand


def store_stiffness_signature(registry: Registry, params: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    """Store a finished stiffness signature as a new version of the hand (the job's ``on_result`` hook)."""
    return _store(registry, params, result, "stiffness", {"object": params["object"]})


def store_capture_signature(registry: Registry, params: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    """Store a finished capture model as a new signature version of the hand (the job's ``on_result`` hook)."""
    return _store(registry, params, result, "capture", {"object": params["object"], "grid": params["grid"]})


def _store(
    registry: Registry, params: dict[str, Any], result: dict[str, Any], kind: str, stored: dict[str, Any]
) -> dict[str, Any]:
    rec = repo.add_signature(
        registry,
        params["hand"],
        kind=kind,
        method=str(params["object"].get("name") or params["object"].get("kind")),
        source="simulation",
        data=result["signature"],
        params=stored,
        hand_revision=params.get("hand_revision"),
        if_match=params.get("if_match"),
        object_digest=object_digest_of(params["object"]),
    )
    return {
        "hand": rec.hand,
        "version": rec.version,
        "etag": rec.etag,
        "links": {"signature": f"/v1/hands/{rec.hand}/signatures/{rec.version}"},
    }


def register_calibrated_variant(registry: Registry, params: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    """Register a finished calibration's variant as a hand of its own (the job's ``on_result`` hook): its folder
    copied into the service's hand storage, loaded and added under the name the request chose."""
    import hashlib
    import shutil
    import uuid
    from pathlib import Path

    source = Path(result.pop("variant_folder"))
    name = str(result.pop("variant_name"))
    folder = Path(params["user_hands_dir"]) / name / uuid.uuid4().hex
    shutil.copytree(source, folder)
    try:
        listing = [
            {
                "path": str(p.relative_to(folder)),
                "size": p.stat().st_size,
                "sha256": hashlib.sha256(p.read_bytes()).hexdigest(),
            }
            for p in sorted(folder.rglob("*"))
            if p.is_file()
        ]
        info = inspect_hand(str(folder / "hand.toml"), Settings(**params["settings"]).limits)
        rec = repo.add_hand(
            registry,
            name=name,
            manifest_path=str(folder / "hand.toml"),
            info=info,
            files=listing,
            folder=str(folder),
        )
    except BaseException:
        repo.remove_hand_folder(folder)
        raise
    return {**result, "variant": {"hand": rec.name, "links": {"hand": f"/v1/hands/{rec.name}"}}}


def default_job_kinds() -> dict[str, JobKind]:
    """The job kinds this service runs, by name."""
    kinds = (
        JobKind(
            "stiffness_signature",
            "softsig_service.services.tasks:run_stiffness_signature",
            "grasp an object in MuJoCo: 6x6 stiffness and break forces; stored as a signature version",
            on_result=store_stiffness_signature,
        ),
        JobKind(
            "capture_signature",
            "softsig_service.services.tasks:run_capture_signature",
            "grasp simulations over relative poses of an object: the capture model of strategy R; stored as a "
            "signature version",
            on_result=store_capture_signature,
        ),
        JobKind(
            "validation",
            "softsig_service.services.tasks:run_validation",
            "simulate a plan's grasp in MuJoCo, trials under object-pose noise",
        ),
        JobKind(
            "calibration",
            "softsig_service.services.tasks:run_calibration",
            "fit a hand's declared parameters to its real outcomes, predict the held-out cells; the calibrated "
            "variant registered as a hand",
            on_result=register_calibrated_variant,
        ),
        JobKind(
            "experiment",
            "softsig_service.services.tasks:run_experiment",
            "the reference experiment (Table I): conditions x objects x strategies x trials",
        ),
    )
    return {k.name: k for k in kinds}


def object_digest_of(obj_json: dict[str, Any]) -> str | None:
    """The shape digest of a stored object's JSON (``TableObject.shape_digest``), None if it no longer parses."""
    from softsig_service.errors import SoftsigError
    from softsig_service.objects import object_from_json

    try:
        return object_from_json(obj_json).shape_digest
    except SoftsigError:
        return None


def register_builtin_hands(registry: Registry, settings: Settings) -> dict[str, str]:
    """Register (or refresh) every built-in hand of ``settings.hands_dir``; returns name -> what happened."""
    done: dict[str, str] = {}
    for name in builtin_hand_names(settings):
        manifest = (settings.hands_dir / name / "hand.toml").resolve()
        info = inspect_hand(str(manifest), settings.limits)
        done[name] = repo.sync_builtin_hand(registry, name=name, manifest_path=str(manifest), info=info)
    return done
