"""A hand as one archive (``.zip``, ``.tar.gz`` or ``.tgz``): safe reading, and packing a folder into one.

An archive holds a hand's folder: ``hand.toml`` at its top, or inside one top-level folder (as ``git archive``
or ``tar czf hand.tar.gz my_hand/`` make it). Reading never touches the disk and applies, to every member, the
rules of a multipart upload (:func:`~softsig_service.hands.assets.check_relative_path`: relative paths that do
not climb out with ``..``) and these limits (:class:`~softsig_service.config.ModelLimits`):

* at most ``max_archive_members`` members (files and folders);
* every file at most ``max_asset_bytes``, all files together at most ``max_total_bytes`` once unpacked, counted
  from the bytes actually read (a member's declared size is checked first, never trusted alone): a zip bomb
  stops at the limit;
* no links (symbolic or hard), devices or pipes; no path twice; nothing under ``.softsig-cache/`` (softsig's own
  cache of expanded xacro files).

Violations raise :class:`~softsig_service.errors.UnsafePath` (paths, links) or
:class:`~softsig_service.errors.ModelTooLarge` (sizes, counts), naming the member (``field = "archive"``).
"""

from __future__ import annotations

import io
import stat
import tarfile
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from softsig_service.config import ModelLimits
from softsig_service.errors import InvalidHandModel, ModelTooLarge, UnsafePath
from softsig_service.hands.assets import check_relative_path
from softsig_service.hands.xacro_expand import CACHE_DIR

ARCHIVE_SUFFIXES = (".zip", ".tar.gz", ".tgz")
FIELD = "archive"


def is_archive(name: str) -> bool:
    """Whether a file name ends with one of :data:`ARCHIVE_SUFFIXES`."""
    return name.lower().endswith(ARCHIVE_SUFFIXES)


def _member_path(name: str) -> str:
    rel = check_relative_path(name, FIELD)
    parts = [p for p in rel.parts if p not in ("", ".")]
    if parts and parts[0] == CACHE_DIR:
        raise UnsafePath(f"{CACHE_DIR}/ is softsig's own cache and cannot be uploaded", field=FIELD, value=name)
    return "/".join(parts)


class _Budget:
    """Counts members and unpacked bytes against the limits."""

    def __init__(self, limits: ModelLimits) -> None:
        self.limits = limits
        self.members = 0
        self.total = 0

    def member(self, name: str) -> None:
        self.members += 1
        if self.members > self.limits.max_archive_members:
            raise ModelTooLarge(
                f"the archive has more than {self.limits.max_archive_members} members", field=FIELD, value=name
            )

    def read(self, name: str, declared: int, stream: IO[bytes]) -> bytes:
        cap = self.limits.max_asset_bytes
        left = self.limits.max_total_bytes - self.total
        if declared > cap:
            raise ModelTooLarge(f"a member is larger than {cap} bytes unpacked", field=FIELD, value=name)
        data = stream.read(min(cap, left) + 1)
        if len(data) > cap:
            raise ModelTooLarge(f"a member is larger than {cap} bytes unpacked", field=FIELD, value=name)
        self.total += len(data)
        if self.total > self.limits.max_total_bytes:
            raise ModelTooLarge(
                f"the archive unpacks to more than {self.limits.max_total_bytes} bytes", field=FIELD, value=name
            )
        return data


def _zip_members(data: bytes, budget: _Budget) -> Iterator[tuple[str, bytes]]:
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile as exc:
        raise InvalidHandModel(f"not a readable zip archive: {exc}", field=FIELD) from None
    with archive:
        for info in archive.infolist():
            budget.member(info.filename)
            mode = info.external_attr >> 16
            if stat.S_ISLNK(mode):
                raise UnsafePath("archives must not contain links", field=FIELD, value=info.filename)
            if info.is_dir():
                _member_path(info.filename)
                continue
            if stat.S_IFMT(mode) not in (0, stat.S_IFREG):  # no type bits: a plain file (as zipfile writes)
                raise UnsafePath("archives may hold only files and folders", field=FIELD, value=info.filename)
            path = _member_path(info.filename)
            with archive.open(info) as stream:
                yield path, budget.read(info.filename, info.file_size, stream)


def _tar_members(data: bytes, budget: _Budget) -> Iterator[tuple[str, bytes]]:
    try:
        archive = tarfile.open(fileobj=io.BytesIO(data), mode="r:*")  # noqa: SIM115 (closed below)
    except (tarfile.TarError, EOFError, OSError) as exc:
        raise InvalidHandModel(f"not a readable tar archive: {exc}", field=FIELD) from None
    with archive:
        try:
            for member in archive:
                budget.member(member.name)
                if member.issym() or member.islnk():
                    raise UnsafePath("archives must not contain links", field=FIELD, value=member.name)
                if member.isdir():
                    _member_path(member.name)
                    continue
                if not member.isfile():
                    raise UnsafePath("archives may hold only files and folders", field=FIELD, value=member.name)
                path = _member_path(member.name)
                stream = archive.extractfile(member)
                assert stream is not None  # a regular file always has one
                yield path, budget.read(member.name, member.size, stream)
        except (tarfile.TarError, EOFError, OSError) as exc:
            raise InvalidHandModel(f"the tar archive is damaged: {exc}", field=FIELD) from None


def read_archive(data: bytes, filename: str, limits: ModelLimits) -> dict[str, bytes]:
    """The files of a hand archive, keyed by their path relative to the hand's folder (``hand.toml`` at the
    top); raises as the module docstring says."""
    if not is_archive(filename):
        raise InvalidHandModel("a hand archive must be a .zip, .tar.gz or .tgz file", field=FIELD, value=filename,
                               choices=ARCHIVE_SUFFIXES)  # fmt: skip
    budget = _Budget(limits)
    reader = _zip_members if filename.lower().endswith(".zip") else _tar_members
    files: dict[str, bytes] = {}
    for path, content in reader(data, budget):
        if path in files:
            raise InvalidHandModel("the archive holds the same path twice", field=FIELD, value=path)
        files[path] = content
    if "hand.toml" not in files:
        tops = {p.split("/", 1)[0] for p in files}
        top = next(iter(tops)) if len(tops) == 1 else None
        if top is None or f"{top}/hand.toml" not in files:
            raise InvalidHandModel("the archive has no hand.toml at its top or in its one top folder", field=FIELD,
                                   value=sorted(files)[:10])  # fmt: skip
        files = {p.split("/", 1)[1]: b for p, b in files.items()}
    return files


def pack_folder(folder: Path, limits: ModelLimits) -> bytes:
    """A ``.tar.gz`` of a hand's folder (without ``.softsig-cache/``), refusing links as the service would."""
    buffer = io.BytesIO()
    total = 0
    with tarfile.open(fileobj=buffer, mode="w:gz") as archive:
        for path in sorted(folder.rglob("*")):
            rel = path.relative_to(folder)
            if rel.parts[0] == CACHE_DIR or path.is_dir():
                continue
            if path.is_symlink() or not path.is_file():
                raise UnsafePath("a hand's folder must hold only files and folders", field=FIELD, value=str(rel))
            total += path.stat().st_size
            if total > limits.max_total_bytes:
                raise ModelTooLarge(f"the hand's files exceed {limits.max_total_bytes} bytes", field=FIELD,
                                    value=str(rel))  # fmt: skip
            archive.add(path, arcname=rel.as_posix(), recursive=False)
    return buffer.getvalue()
