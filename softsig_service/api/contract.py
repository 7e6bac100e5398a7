"""The OpenAPI document as the running service enforces it: the parts that depend on its settings.

FastAPI derives the document from the routes, which do not know the settings. Three things the service enforces do
depend on them, and :func:`apply_settings` writes them into the document, so that a client (or a conformance
checker) generated from ``/openapi.json`` is told what the service does:

- reads (``GET`` under ``/v1``) declare the API-key security scheme and a 401 only when ``read_auth`` is on;
- ``If-Match`` on updates and deletes of a hand is required when ``require_if_match`` is on (else optional);
- the ``trials`` of a validation are at most ``max_job_trials``, and of an experiment at most
  ``max_job_trials // cells`` per cell (a field whose default is above its cap is required: leaving it out is
  refused).

``openapi/openapi.json`` is the document of the default settings.

A route that reads its body itself (``POST /v1/objects`` takes JSON or a multipart file) names its JSON body's
schema by reference; :func:`add_body_models` puts those models into the document's components.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from softsig_service.api.deps import IF_MATCH_REQUIRED_DESCRIPTION
from softsig_service.config import Settings
from softsig_service.experiments.campaign_spec import TABLE1_CELLS

_READS = frozenset({"get", "head"})


def apply_settings(document: dict[str, Any], settings: Settings) -> dict[str, Any]:
    """``document`` (FastAPI's OpenAPI document of the app, changed in place and returned) as ``settings`` make
    the service behave."""
    for path, item in document.get("paths", {}).items():
        for method, operation in item.items():
            if not isinstance(operation, dict):
                continue
            if method in _READS and path.startswith("/v1/") and not settings.read_auth:
                operation.pop("security", None)
                operation.get("responses", {}).pop("401", None)
            for parameter in operation.get("parameters", []):
                if parameter.get("in") == "header" and parameter.get("description") == IF_MATCH_REQUIRED_DESCRIPTION:
                    parameter["required"] = settings.require_if_match
    schemas = document.get("components", {}).get("schemas", {})
    _cap(schemas, "ValidationIn", "trials", settings.max_job_trials)
    # below one trial per cell no experiment fits: the maximum then says so (0, under the minimum of 1)
    _cap(schemas, "ExperimentIn", "trials", settings.max_job_trials // TABLE1_CELLS)
    return document


def add_body_models(document: dict[str, Any], models: tuple[type[BaseModel], ...]) -> dict[str, Any]:
    """``document`` (changed in place and returned) with the JSON schemas of ``models`` and the models they use in
    ``components.schemas`` (a schema FastAPI already wrote for another route is kept: it is the same model)."""
    schemas = document.setdefault("components", {}).setdefault("schemas", {})
    for model in models:
        schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
        for name, sub in schema.pop("$defs", {}).items():
            schemas.setdefault(name, sub)
        schemas.setdefault(model.__name__, schema)
    return document


def _cap(schemas: dict[str, Any], model: str, field: str, most: int) -> None:
    """Lower the ``maximum`` of ``model.field`` to ``most`` (when the model is in the document); a default above it
    is dropped and the field made required."""
    schema = schemas.get(model, {})
    prop = schema.get("properties", {}).get(field)
    if prop is None:
        return
    prop["maximum"] = min(int(prop.get("maximum", most)), most)
    if prop.get("default", most) > most:
        del prop["default"]
        schema["required"] = sorted({*schema.get("required", []), field})
