"""A job's result files: listing them, resolving a requested name safely inside the job's folder, and their media
types by suffix."""

from __future__ import annotations

from pathlib import Path

MEDIA_TYPES = {
    ".json": "application/json",
    ".csv": "text/csv",
    ".md": "text/markdown",
    ".png": "image/png",
    ".txt": "text/plain",
    ".svg": "image/svg+xml",
    ".pdf": "application/pdf",
    ".mp4": "video/mp4",
    ".jsonl": "application/x-ndjson",
}


def media_type(name: str) -> str:
    """Media type of a result file by its suffix (``application/octet-stream`` when unknown)."""
    return MEDIA_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")


def list_files(folder: Path) -> list[tuple[str, int]]:
    """Result files under ``folder`` (recursively): (relative POSIX path, size [bytes]), sorted."""
    if not folder.is_dir():
        return []
    out = []
    for p in sorted(folder.rglob("*")):
        if p.is_file() and not p.is_symlink():
            out.append((p.relative_to(folder).as_posix(), p.stat().st_size))
    return out


def resolve_file(folder: Path, name: str) -> Path | None:
    """The file ``name`` inside ``folder``, or None if it is not a regular file there (no escapes, no links)."""
    if not name or name.startswith(("/", "\\")) or ".." in Path(name).parts:
        return None
    path = (folder / name).resolve()
    if not path.is_relative_to(folder.resolve()) or not path.is_file() or (folder / name).is_symlink():
        return None
    return path
