"""Output folders that never mislead: checked before the work, written aside, published whole.

A run or a study writes its files into a fresh hidden folder beside ``--out`` (the *stage*),
made before the solve, so that an unwritable or full destination is found before minutes of work.
Only when everything was written is the stage published: the files of an earlier cfm output in
``--out`` (those its manifest lists, or cfm's known output names for outputs written before
manifests existed) are removed and the new files moved in, with a manifest
(:data:`MANIFEST`) naming them. Files cfm did not write are never touched. A failure removes the
stage and leaves ``--out`` as it was, so no folder ever holds the files of two runs. A file the
command names as its input (``inputs``) is never removed or replaced: an output that would do
so is refused (:func:`refuse_inputs`). An earlier output that cannot be replaced whole (one of its
files made immutable, in a folder that refuses changes) is refused before anything is removed
(:func:`check_changeable`). A file made later from an output and written into its folder (``cfm
fields RUN --png RUN/cut.png``) is recorded in its manifest (:func:`adopt`) and goes with it.

Public API: :func:`staged_folder` (a context manager), :func:`check_folder_target`,
:func:`check_file_target`, :func:`check_changeable`, :func:`refuse_inputs`, :func:`adopt`.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import sys
from glob import escape as glob_escape
from pathlib import Path

from ..errors import InputError

#: File in a published folder listing the files cfm wrote there (JSON: {"files": [...]})
MANIFEST = ".cfm-output.json"

#: Names cfm writes (and wrote before manifests existed, version 0.2.0 and older): treated as cfm's
#: own in a folder without a manifest, or whose manifest was lost, so that a new output there never
#: sits beside an earlier one's files.
LEGACY_NAMES = ("summary.json", "scene.toml", "acceleration.csv", "acceleration.png", "reaction.csv",
                "reaction.png", "specimen.pvd", "fields.json", "sweep.csv", "sweep.parquet", "sweep.json",
                "peaks.png", "fit.json", "fit.png", "objective.png", "fitted-scene.toml", "fitted_scene.toml",
                "report.json", "report.md")
LEGACY_PATTERNS = ("specimen_*.vtu", "impactor_*.vtu")

#: Files whose presence means an output is complete: published last.
MARKERS = ("summary.json", "fit.json", "sweep.json", "report.json")

#: Free space kept beyond what an output needs (bytes).
SPACE_MARGIN = 16 * 2**20


def _existing_ancestor(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _probe_name(folder: Path) -> Path:
    return folder / f".cfm-probe-{os.getpid()}-{secrets.token_hex(4)}"


def _touch(folder: Path) -> None:
    """Create and remove a file in ``folder`` (raises OSError): the only reliable writability test
    (root ignores modes; ``chattr +i`` and read-only mounts do not show in ``os.access``)."""
    probe = _probe_name(folder)
    probe.write_bytes(b"")
    probe.unlink()


def _probe(folder: Path, what: str, target: Path) -> None:
    """:func:`_touch` ``folder``, refused with a message naming ``target``."""
    try:
        _touch(folder)
    except OSError as exc:
        raise InputError(f"{what} {target} cannot be written: {folder} refuses new files "
                         f"({exc.strerror or exc}); choose a folder you can write to.") from None


def _move_aside_and_back(path: Path) -> None:
    """Rename ``path`` to a hidden name in its folder and back (raises OSError if it cannot be
    renamed): what removing or replacing it needs (its folder writable, the entry neither
    immutable nor append-only, not another user's in a sticky folder), tested by doing it.
    Call it with signals deferred (:func:`deferred_signals`)."""
    aside = _probe_name(path.parent)
    os.rename(path, aside)
    os.rename(aside, path)


def _blocker(path: Path) -> tuple[Path, OSError] | None:
    """The first entry that keeps ``path`` (a file, a link, or a folder with all it holds) from
    being removed or rewritten, with the error; None when every entry can be. Each entry is moved
    aside and back (:func:`_move_aside_and_back`), each folder is probed with a new file."""
    todo = [path]
    while todo:
        entry = todo.pop()
        try:
            _move_aside_and_back(entry)
            if entry.is_dir() and not entry.is_symlink():
                _touch(entry)
                todo.extend(sorted(entry.iterdir(), reverse=True))
        except OSError as exc:
            return entry, exc
    return None


def _first_blocker(entries) -> tuple[Path, OSError] | None:
    """:func:`_blocker` of each existing entry in turn, with SIGINT and SIGTERM deferred (an entry
    is never left under its temporary name); the first entry that cannot be changed and why."""
    found = None
    with deferred_signals() as caught:
        for entry in entries:
            if entry.exists() or entry.is_symlink():
                found = _blocker(Path(entry))
                if found is not None:
                    break
    redeliver(caught, None)
    return found


def check_changeable(out, entries, what: str = "--out") -> None:
    """Refuse an output in ``out`` when one of ``entries`` (the earlier output's files and folders
    it removes or rewrites: a sweep's run cache it writes into) cannot be changed, before any of
    them is: a file made immutable (``chattr +i``), a folder that refuses changes, another user's
    file in a sticky folder. Without this check, publication stopped at that entry with part of
    the earlier output already gone.

    Parameters
    ----------
    out : pathlib.Path
        The output folder.
    entries : iterable of pathlib.Path
        Entries in ``out`` (missing ones are skipped); a folder is checked with all it holds.
    what : str
        How messages name ``out``.

    Raises
    ------
    InputError
        Naming the first entry that cannot be changed, why, and what to do; nothing was changed.
    """
    found = _first_blocker(entries)
    if found is not None:
        entry, exc = found
        raise InputError(f"{what} {out}: {entry} cannot be removed or rewritten ({exc.strerror or exc}), but writing "
                         f"the output there changes it (it belongs to the earlier cfm output in {out}); nothing was "
                         f"changed. Make it changeable (made immutable: chattr -i; another user's, or in a read-only "
                         f"folder: ask its owner), or choose another {what} folder.")


def _check_space(folder: Path, need_bytes: int, what: str, target: Path) -> None:
    if need_bytes <= 0:
        return
    free = shutil.disk_usage(folder).free
    if free < need_bytes + SPACE_MARGIN:
        raise InputError(f"{what} {target}: the output needs about {need_bytes / 2**20:.4g} MiB but only "
                         f"{free / 2**20:.1f} MiB are free on that disk; free some space or choose another folder "
                         f"(or store fewer frames: option frame_interval).")


def _refuse_empty(path, what: str, kind: str) -> None:
    """An empty string names no path (``Path("")`` is the current folder): refused."""
    if isinstance(path, (str, bytes)) and not path:
        raise InputError(f"{what} is empty; give a {kind}.")


def check_folder_target(out, what: str = "--out", need_bytes: int = 0, inputs=(), keep: tuple[str, ...] = ()) -> Path:
    """Check that ``out`` can become an output folder, before any work is done.

    Parameters
    ----------
    out : str or path-like
        The folder (it may not exist yet).
    what : str
        How messages name it (``"--out"``, ``"output directory"``).
    need_bytes : int
        Bytes the output will take (0: not checked); refused when the disk has less free space
        plus :data:`SPACE_MARGIN`.
    inputs : iterable of path-like
        The files the command reads (None and empty entries are skipped): none of them may be a
        file that publishing an output in ``out`` removes (:func:`refuse_inputs`).
    keep : tuple of str
        Entries of the earlier output that the new one keeps (not checked for removal).

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    InputError
        ``out`` is empty text, or it or one of its parents is a file, it or the folder it would be
        made in cannot be written, the disk is too full, one of ``inputs`` is a file of the
        earlier cfm output in ``out``, or a file of that output cannot be removed
        (:func:`check_changeable`).
    """
    _refuse_empty(out, what, "folder")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{what} {out} exists and is not a directory; name a folder (new or of an earlier run).")
    base = _existing_ancestor(out)
    if not base.is_dir():
        raise InputError(f"{what} {out}: {base} is a file, so no folder can be made there; choose another path.")
    _probe(base, what, out)
    if out.exists():
        _probe(out, what, out)
    _check_space(base, need_bytes, what, out)
    refuse_inputs(out, inputs, what)
    if out.is_dir():
        check_changeable(out, [p for p in earlier_files(out) if p.name not in keep], what)
    return out


def refuse_inputs(out, inputs, what: str = "--out", names=(), keep: tuple[str, ...] = ()) -> None:
    """Refuse an output in ``out`` that would remove or replace a file the command reads.

    Publishing an output removes the earlier cfm output's files there (:func:`earlier_files`:
    those its manifest lists, or cfm's known output names) and puts the new files in their place:
    an input among them (``cfm fit --scene run/scene.toml --out run``, ``cfm calibrate --data
    run/acceleration.csv --out run``) would be gone after the command, though the command read it.

    Parameters
    ----------
    out : str or path-like
        The output folder (it may not exist yet).
    inputs : iterable of path-like
        The files the command reads; None and empty entries are skipped. A file is matched under
        any spelling or link.
    what : str
        How messages name ``out``.
    names : iterable of str
        Names of the new output's files (known once it is written), which replace files of the
        same name in ``out``.
    keep : tuple of str
        Earlier entries the publication keeps (:func:`publish`).

    Raises
    ------
    InputError
        Naming the input, why it would go, and what to do instead.
    """
    out = Path(out)
    given = [Path(p) for p in inputs if p]
    if not given or not out.is_dir():
        return
    earlier = "of the earlier cfm output there, which this command's output replaces"
    going = [(f, earlier) for f in earlier_files(out) if f.name not in keep and f.name != MANIFEST]
    going += [(out / n, "of the same name as a file this command writes") for n in names]
    for path, why in going:
        hit = next((g for g in given if _same_file(path, g)), None)
        inner = None if hit is not None else next((g for g in given if _inside(g, path)), None)
        if hit is not None or inner is not None:
            where = f"is a file {why}" if hit is not None else f"lies in {path.name}/, a folder {why}"
            raise InputError(f"{what} {out}: the input {hit or inner} {where}, so writing the output there would "
                             f"remove a file this command reads. Choose another {what} folder, or copy the file out "
                             f"of {out} and give the copy.")


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies in the folder ``folder`` (not a link to one), links resolved."""
    try:
        return (folder.is_dir() and not folder.is_symlink()
                and Path(path).resolve().is_relative_to(folder.resolve()))
    except OSError:
        return False


def check_file_target(path, what: str = "--out", need_bytes: int = 0, suffix: str | None = None,
                      inputs=()) -> Path:
    """Check that ``path`` can be written as a file, before any work is done.

    Parameters
    ----------
    path : str or path-like
        The file (it may exist: it is replaced atomically when written).
    what : str
        How messages name it (``"--out"``, ``"--plot"``, ``"--json"``).
    need_bytes : int
        Bytes the file will take (0: not checked).
    suffix : str, optional
        The file's kind (``".png"``, ``".json"``): another suffix is refused, so that a slip of
        the argument (``--plot run/acceleration.csv``) cannot write a picture over a data file.
    inputs : iterable of path-like
        The files the command reads (a folder stands for the files a run folder's readers take:
        summary.json, acceleration.csv, reaction.csv): ``path`` may not be one of them, under any
        spelling or link (``cfm point --history F.csv --out ./F.csv``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        ``path`` is empty text or an existing directory, has another suffix than ``suffix``, is one
        of the files of a cfm output folder (listed in its manifest: a run's acceleration.csv,
        specimen.pvd, ...), is one of ``inputs``, a parent is a file, the folder cannot be written,
        ``path`` exists and cannot be replaced (immutable, another user's in a sticky folder) or
        the disk is too full.
    """
    _refuse_empty(path, what, "file")
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{what} {path} is an existing directory, but a file is written there; name a file "
                         f"(e.g. {path / 'out'}{suffix or path.suffix or ''}).")
    if suffix is not None and path.suffix.lower() != suffix:
        raise InputError(f"{what} {path}: a {suffix[1:].upper()} file is written there, but the name ends in "
                         f"{path.suffix or 'no suffix'}; name a {suffix} file.")
    for given in map(Path, inputs):
        read = [given / n for n in ("summary.json", "acceleration.csv", "reaction.csv")] if given.is_dir() else [given]
        hit = next((f for f in read if _same_file(path, f)), None)
        if hit is not None:
            raise InputError(f"{what} {path} is {hit}, a file this command reads; writing there would destroy its "
                             f"input. Name another file.")
    owner = path.parent
    if (path.exists() and (owner / MANIFEST).is_file()
            and path.name in {*_manifest_names(owner), MANIFEST}):
        raise InputError(f"{what} {path} is a file of the cfm output in {owner} (listed in its {MANIFEST}); "
                         f"writing there would replace it and leave that output incomplete. Choose another name "
                         f"or folder.")
    base = _existing_ancestor(path.parent)
    if not base.is_dir():
        raise InputError(f"{what} {path}: {base} is a file, so no folder can be made there; choose another path.")
    _probe(base, what, path)
    found = _first_blocker([path])   # a directory was refused above
    if found is not None:
        error = found[1]
        raise InputError(f"{what} {path} exists and cannot be replaced ({error.strerror or error}); make it "
                         f"changeable (made immutable: chattr -i; another user's: ask its owner) or name another "
                         f"file.")
    _check_space(base, need_bytes, what, path)
    return path


def earlier_files(out: Path) -> list[Path]:
    """Files of an earlier cfm output in ``out``: those its manifest lists, or cfm's legacy names.

    Parameters
    ----------
    out : pathlib.Path
        An existing folder.

    Returns
    -------
    list of pathlib.Path
        Existing files (the manifest itself included, and the files made later from the output
        that it records: :func:`adopt`), sorted; folders listed in a manifest are included as
        folders.
    """
    found: set[Path] = set()
    manifest = out / MANIFEST
    if manifest.is_file():
        found.update(out / n for n in (*_manifest_names(out), *_manifest_names(out, DERIVED))
                     if "/" not in n and n not in ("", ".", ".."))
        found.add(manifest)
    elif legacy_output(out):
        found.update(out / n for n in LEGACY_NAMES)
        for pattern in LEGACY_PATTERNS:
            found.update(out.glob(pattern))
    return sorted(p for p in found if p.exists() or p.is_symlink())


#: Keys of which a completion marker (:data:`MARKERS`) written by cfm before manifests holds at least one.
LEGACY_KEYS = ("provenance", "backend", "units")


def legacy_output(out: Path) -> bool:
    """Whether ``out`` (no manifest) holds a cfm output written before manifests existed: one of its
    completion markers (:data:`MARKERS`) reads as a JSON object with one of :data:`LEGACY_KEYS`.
    File names alone do not make an output: a user's own acceleration.csv or summary.json in a
    folder cfm never wrote was removed as "the earlier output" by a fit or sweep written there.

    Parameters
    ----------
    out : pathlib.Path
        An existing folder without a manifest.

    Returns
    -------
    bool
    """
    for name in MARKERS:
        try:
            doc = json.loads((out / name).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(doc, dict) and any(key in doc for key in LEGACY_KEYS):
            return True
    return False


#: Suffixes of result files (plots, tables, data): such a file left beside a new output is named.
RESULT_SUFFIXES = (".png", ".json", ".csv", ".vtu", ".pvd", ".parquet", ".pdf", ".svg")

#: The kind of output a file marks (the first found, in this order).
KINDS = (("sweep.json", "sweep"), ("fit.json", "fit"), ("report.json", "verification report"),
         ("manifest.json", "material export"), ("summary.json", "run"))


def output_kind(names) -> str | None:
    """The kind of cfm output a folder's file names make (:data:`KINDS`), None if none."""
    names = set(names)
    return next((kind for marker, kind in KINDS if marker in names), None)


def remove_entry(path: Path) -> None:
    """Remove a file, link or folder (with its contents) of an output.

    Parameters
    ----------
    path : pathlib.Path
        The entry; missing is fine.
    """
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def replaced_note(out: Path, earlier: list[Path], now: str | None) -> None:
    """Say on stderr that ``out``'s earlier output of another kind is being replaced (a mistyped
    ``--out``: a sweep written into a run's folder), naming that kind and how many files go."""
    before = output_kind(p.name for p in earlier)
    if before is not None and now is not None and before != now:
        count = len([p for p in earlier if p.name != MANIFEST])
        print(f"note: {out} held the output of a {before} ({count} file{'' if count == 1 else 's'}); "
              f"it is replaced by this {now}'s.", file=sys.stderr)


class PublishError(OSError):
    """The stage could not be moved into ``--out``; ``touched`` says whether the earlier output
    there was already (partly) removed when it failed."""

    def __init__(self, cause: OSError, touched: bool):
        super().__init__(cause.errno, cause.strerror or str(cause))
        self.touched = touched


def publish(stage: Path, out: Path, keep: tuple[str, ...] = (), inputs=(), what: str = "--out") -> list[str]:
    """Move a finished stage's files into ``out``, replacing an earlier cfm output there.

    Every entry it removes or replaces (the earlier output's files, the manifest, a file of a name
    the stage holds) is first checked to be removable (:func:`check_changeable`): one that is not
    (a file of another user, ``chattr +i``) stops the publication before anything changed. The
    order keeps every intermediate state honest: the earlier output's completion markers
    (:data:`MARKERS`) go first, so a folder interrupted mid-way never looks complete; the
    manifest then lists the earlier and the new files until the end,
    so that a later run still finds and removes them; the new markers come last. Call it with
    SIGINT and SIGTERM deferred (:func:`deferred_signals`, as :func:`staged_folder` does).

    Parameters
    ----------
    stage : pathlib.Path
        The folder holding the new output (removed afterwards).
    out : pathlib.Path
        The destination (created if missing).
    keep : tuple of str
        Names of earlier entries to keep (a study's resumable run cache), unless the stage holds
        a new entry of the same name.
    inputs : iterable of path-like
        Files the command read: if one of them would be removed or replaced, nothing is
        published (:func:`refuse_inputs`).
    what : str
        How messages name ``out``.

    Returns
    -------
    list of str
        The names published (also written to the manifest).

    Raises
    ------
    PublishError
        A file could not be removed or moved; ``touched`` False: ``out`` is as it was.
    InputError
        One of ``inputs`` would be removed or replaced, or an entry to remove or replace cannot
        be (:func:`check_changeable`); ``out`` is as it was.
    """
    names = sorted(p.name for p in stage.iterdir())
    refuse_inputs(out, inputs, what, names=names, keep=keep)
    if not out.exists():
        try:
            _write_manifest(stage, names)
            os.replace(stage, out)
        except OSError as exc:
            raise PublishError(exc, touched=False) from None
        return names
    earlier = earlier_files(out)
    going = [old for old in earlier if (old.name not in keep or old.name in names) and old.name != MANIFEST]
    gone = {p.name for p in going}  # removed below: not "kept"
    foreign = [out / n for n in names if n not in gone and n != MANIFEST
               and ((out / n).exists() or (out / n).is_symlink())]  # a file cfm did not write, of a name it writes
    check_changeable(out, [*going, out / MANIFEST, *foreign], what)  # before anything changes
    replaced_note(out, earlier, output_kind(names))
    if foreign:
        print(f"note: {out} held {', '.join(p.name for p in foreign)}, not of an earlier cfm output there, of the "
              f"name{'' if len(foreign) == 1 else 's'} this command writes: replaced by its file"
              f"{'' if len(foreign) == 1 else 's'}.", file=sys.stderr)
    read = [Path(p) for p in inputs if p]  # the command's own inputs are not "made from the earlier output"
    others = sorted(p.name for p in out.iterdir() if p.suffix.lower() in RESULT_SUFFIXES and p.name not in names
                    and p.name not in keep and p.name not in gone and not p.name.startswith(".")
                    and not any(_same_file(p, f) for f in read))
    if earlier and others:  # cfm fields --png out/x/cut.png, cfm compare --json out/x/c.json: of the run now gone
        print(f"note: {out} keeps {', '.join(others[:6])}{' ...' if len(others) > 6 else ''}, not written by this "
              f"command: if they were made from the earlier output there, they no longer describe the folder's "
              f"files.", file=sys.stderr)
    touched = False
    try:
        for old in sorted(going, key=lambda p: p.name not in MARKERS):  # the earlier completion markers first
            remove_entry(old)
            touched = True
        kept = [k for k in keep if (out / k).exists() and k not in names]
        _write_manifest(out, sorted({*names, *kept, *(p.name for p in going)}))
        touched = True
        for name in sorted(names, key=lambda n: (n in MARKERS, n)):  # the new completion marker last
            target = out / name
            if target.exists() or target.is_symlink():
                remove_entry(target)  # a foreign file of a name cfm writes: replaced by the new output
            os.replace(stage / name, target)
        _write_manifest(out, sorted({*names, *kept}))
    except OSError as exc:
        raise PublishError(exc, touched) from None
    shutil.rmtree(stage, ignore_errors=True)
    return names


@contextlib.contextmanager
def deferred_signals():
    """Hold SIGINT and SIGTERM back for the duration of the block (a few milliseconds of file
    moves), then deliver them: a Ctrl-C cannot cut a publication in half. The caught signals are
    yielded as a list; the block's caller re-raises them (:func:`redeliver`). Outside the main
    thread (where Python cannot set handlers) the block runs as it is."""
    import signal
    import threading

    caught: list[tuple] = []  # (signal, the handler it would have met)
    if threading.current_thread() is not threading.main_thread():
        yield caught
        return
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig in saved:
        signal.signal(sig, lambda signum, frame: caught.append((signum, saved[signum])))
    try:
        yield caught
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


def redeliver(caught: list, published: Path | None) -> None:
    """Act on the signals :func:`deferred_signals` held back, as their handlers would have: the
    exception a handler raises (KeyboardInterrupt, the console script's Terminated) gets the
    attribute ``published`` (the folder written whole before the signal, or None)."""
    import signal

    for sig, handler in caught[:1]:
        if callable(handler):
            try:
                handler(sig, None)
            except BaseException as exc:
                exc.published = published
                raise
        elif handler == signal.SIG_DFL:
            os.kill(os.getpid(), sig)


def published_files(out) -> list[str]:
    """The names of the files the last cfm output published in ``out`` (its manifest; [] if none),
    for a command's "wrote ..." line."""
    return _manifest_names(Path(out))


def _manifest_names(out: Path, key: str = "files") -> list[str]:
    """The file names ``out``'s manifest lists under ``key`` ([] when it is missing or unreadable)."""
    try:
        names = json.loads((out / MANIFEST).read_text(encoding="utf-8")).get(key, [])
    except (OSError, ValueError, AttributeError):
        return []
    return [n for n in names if isinstance(n, str)] if isinstance(names, list) else []


#: Key of a manifest listing the files made later from the output and written into its folder (:func:`adopt`).
DERIVED = "derived"


def adopt(path, sources=()) -> bool:
    """Record a file just written into a cfm output's folder, and made from that output, in its
    manifest (under :data:`DERIVED`), so that the output replacing that folder's later removes it
    with the rest: ``cfm fields RUN --png RUN/cut.png`` left a picture of the earlier run beside
    the files of the next one written into RUN.

    Parameters
    ----------
    path : str or path-like
        The file written.
    sources : iterable of path-like
        The output folders the file was made from: only when its folder is one of them (under any
        spelling or link) and holds a manifest is it recorded.

    Returns
    -------
    bool
        Whether it was recorded. A manifest that cannot be rewritten leaves the file unrecorded
        (the next output there names it as kept, not written by it).
    """
    path = Path(path)
    folder = path.parent
    if not (folder / MANIFEST).is_file() or not path.is_file() or path.name == MANIFEST:
        return False
    if not any(_same_file(folder, Path(s)) for s in sources if s):
        return False
    try:
        doc = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        if not isinstance(doc, dict):
            return False
        if path.name in _manifest_names(folder) or path.name in _manifest_names(folder, DERIVED):
            return True
        doc[DERIVED] = sorted({*_manifest_names(folder, DERIVED), path.name})
    except (OSError, ValueError):
        return False
    tmp = folder / f".{MANIFEST}.{os.getpid()}.tmp"
    try:
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        os.replace(tmp, folder / MANIFEST)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        return False
    return True


def _write_manifest(folder: Path, names: list[str]) -> None:
    tmp = folder / f".{MANIFEST}.{os.getpid()}.tmp"
    tmp.write_text(json.dumps({"written_by": "cfm-materials", "files": names}, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, folder / MANIFEST)


@contextlib.contextmanager
def staged_folder(out, what: str = "--out", need_bytes: int = 0, overwrite: bool = True, keep: tuple[str, ...] = (),
                  inputs=()):
    """Write an output into a stage beside ``out`` and publish it only if the block succeeds.

    Use it around the whole work, so that the destination is checked before the solve::

        with staged_folder(args.out) as stage:
            outcome = cfm.drop_test(scene)
            outcome.save(stage)

    Parameters
    ----------
    out : str or path-like
        The output folder (new, or one holding an earlier cfm output).
    what : str
        How messages name it (``"--out"``, ``"output directory"``).
    need_bytes : int
        Estimated size of the output (bytes; 0: not checked).
    overwrite : bool
        False: refuse (InputError, before any work) when ``out`` holds an earlier cfm output.
    keep : tuple of str
        Entries of the earlier output to keep (e.g. a sweep's resumable ``runs`` folder).
    inputs : iterable of path-like
        Files the command reads: an output that would remove or replace one of them is refused,
        before the block (an earlier output's file) or, for a name only the new output writes,
        after it with nothing published (:func:`refuse_inputs`).

    Yields
    ------
    pathlib.Path
        The stage folder to write into (hidden, beside ``out``).

    Raises
    ------
    InputError
        From :func:`check_folder_target` (an earlier output there that cannot be removed whole
        included) or :func:`refuse_inputs`, or ``overwrite`` is False and ``out`` holds an
        earlier output. Exceptions of the block propagate after the stage is
        removed; ``out`` is untouched.
    """
    inputs = [p for p in inputs if p]
    out = check_folder_target(out, what, need_bytes, keep=keep)  # an earlier output that cannot be removed too
    refuse_inputs(out, inputs, what, keep=keep)
    if not overwrite and out.is_dir() and earlier_files(out):
        raise InputError(f"{what} {out} holds the files of an earlier run ({', '.join(p.name for p in earlier_files(out)[:4])}"
                         f"{', ...' if len(earlier_files(out)) > 4 else ''}); without overwriting, choose a new folder "
                         f"or drop the no-overwrite flag (its files are then replaced).")
    parent = out.absolute().parent
    made = _missing_folders(parent)  # the folders made for the stage: removed again if nothing is published
    try:
        parent.mkdir(parents=True, exist_ok=True)
        remove_stale_stages(parent, out.absolute().name)
        stage = parent / f".{out.absolute().name}{STAGE_TAG}{os.getpid()}-{secrets.token_hex(4)}"
        stage.mkdir()
    except OSError as exc:
        _remove_empty(made)
        raise InputError(f"{what} {out} cannot be written: {exc.strerror or exc}; choose a folder you can write to.") from None
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        _remove_empty(made)
        raise
    with deferred_signals() as caught:
        try:
            publish(stage, out, keep, inputs, what)
        except InputError:
            shutil.rmtree(stage, ignore_errors=True)
            _remove_empty(made)
            raise
        except PublishError as exc:
            shutil.rmtree(stage, ignore_errors=True)
            _remove_empty(made)
            state = ("the earlier output there was partly removed and the folder now holds no complete output "
                     "(no completion marker such as summary.json); run the command again into a folder you can "
                     "write" if exc.touched else "nothing was published and the folder is as it was")
            raise InputError(f"{what} {out}: the finished output could not be moved into place ({exc.strerror}); "
                             f"{state}.") from None
    redeliver(caught, out)


#: Infix of a stage folder's name: ``.<out name>.cfm-stage-<pid>-<random>``.
STAGE_TAG = ".cfm-stage-"


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and its parents that do not exist yet, deepest first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


def _remove_empty(folders: list[Path]) -> None:
    """Remove the folders (deepest first) that are still empty: those a failed output made."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (on this machine; a process of another user counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def remove_stale_stages(parent: Path, name: str) -> list[Path]:
    """Remove the stages of output ``name`` in ``parent`` left by processes that no longer run (a
    command killed with SIGKILL, or a machine that went down, cannot remove its own).

    Parameters
    ----------
    parent : pathlib.Path
        The folder holding the output folder.
    name : str
        The output folder's name.

    Returns
    -------
    list of pathlib.Path
        The stages removed. A stage of a running process (another command writing the same
        output now) is kept.
    """
    removed = []
    for stage in parent.glob(f".{glob_escape(name)}{STAGE_TAG}*"):
        pid = stage.name[len(f".{name}{STAGE_TAG}"):].split("-", 1)[0]
        if stage.is_dir() and pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            shutil.rmtree(stage, ignore_errors=True)
            removed.append(stage)
    return removed
