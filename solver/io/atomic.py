"""Output files written whole or not at all, and output paths checked
before the work that fills them.

``write_files({path: data, ...})`` writes every file to a temporary name in
its own folder, flushed to the disk, and renames them into place only when
all are complete: a full disk, a lost permission or an interrupt leaves the
old files (or none), never a truncated one, and a group of files that go
together (MEDIT ``.mesh`` + ``.fra`` + ``.perm``) is not left half-written.
Every writer of ``solver.io`` goes through it.  An operating-system failure
becomes an ``OutputError`` that names the file and the cause.

``check_output_path(path, what, formats)`` refuses, before any solve, a path
that could not be written: an extension of no format written here, a
folder, a device such as /dev/full, a missing folder, a folder that does
not accept a new file (tried by creating and removing one) or a full disk.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile

from ..errors import OutputError

# a folder with less free space than this is full for any output written here
MIN_FREE_BYTES = 64 * 1024
_PREFIX = ".symframes-"


def _umask() -> int:
    """The process's umask (mkstemp makes files private; outputs get the
    mode an ordinary write would give them)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:  # Linux: read without changing it
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _target(path) -> str:
    """The file a write to path replaces: a symbolic link's target, so that
    the link survives the rename."""
    path = os.fspath(path)
    return os.path.realpath(path) if os.path.islink(path) else path


def os_error_message(path: str, e: OSError, after: str = "") -> str:
    """What went wrong writing path, and what to do, from the OS error;
    ``after`` ends the message."""
    folder = os.path.dirname(os.path.abspath(path)) or os.sep
    code = e.errno
    if code in (errno.ENOSPC, getattr(errno, "EDQUOT", -1)):
        why = ("the disk holding " + folder + (" is full" if code == errno.ENOSPC else " is past its quota")
               + "; free some space or write to another disk")
    elif code in (errno.EACCES, errno.EPERM):
        why = f"permission denied: the folder {folder} does not accept this file; choose a folder you can write to"
    elif code == errno.EROFS:
        why = f"the folder {folder} is on a read-only file system; choose another folder"
    elif code == errno.ENOENT:
        why = f"the folder {folder} does not exist (any more); create it or choose another folder"
    elif code == errno.EISDIR:
        why = "it is a folder; give a file name inside it"
    else:
        why = f"{e.strerror or e}; choose another path"
    return f"cannot write {path}: {why}{after}"


def write_files(files: dict, what: str = "") -> list[str]:
    """Write files whole or not at all (module docs).

    Parameters
    ----------
    files : dict path -> str, bytes, or callable(binary file object)
        A str is written as UTF-8; a callable writes the file itself (e.g.
        ``lambda fh: np.savez_compressed(fh, ...)``).
    what : prefix of the error message, e.g. "--export out.vtu"

    Returns
    -------
    list of str
        The paths written, as given.

    Raises
    ------
    OutputError
        An operating-system error (disk full, permission, a folder in the
        way); every temporary file is removed and no path is changed.
    """
    mode = 0o666 & ~_umask()
    temps: list[tuple[str, str]] = []
    current = ""
    for path in files:
        if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
            raise OutputError((f"{what}: " if what else "") + f"output path {path!r}: must be a file path (a "
                              "non-empty string)")
    try:
        for path, data in files.items():
            current = os.fspath(path)
            target = _target(current)
            folder = os.path.dirname(os.path.abspath(target))
            fd, tmp = tempfile.mkstemp(prefix=_PREFIX, suffix=".part", dir=folder)
            temps.append((target, tmp))
            with os.fdopen(fd, "wb") as fh:
                if callable(data):
                    data(fh)
                else:
                    fh.write(data.encode("utf-8") if isinstance(data, str) else data)
                fh.flush()
                # a full disk may only show when the data reach it
                os.fsync(fh.fileno())
            os.chmod(tmp, mode)
        for target, tmp in temps:
            current = target
            if os.path.isdir(target):
                raise IsADirectoryError(errno.EISDIR, "is a folder", target)
            os.replace(tmp, target)
    except OSError as e:
        kept = "the old file is kept" if os.path.isfile(_target(current)) else "no file was made"
        raise OutputError((f"{what}: " if what else "") + os_error_message(current, e, f"; {kept}")) from None
    finally:
        for _, tmp in temps:
            if os.path.exists(tmp):
                try:
                    os.remove(tmp)
                except OSError:
                    pass
    return [os.fspath(p) for p in files]


def write_text(path, text: str) -> None:
    """One text file, whole or not at all."""
    write_files({path: text})


def check_output_path(path, what: str, formats=None, *, suffix_files=()) -> str:
    """Refuse, before any work, an output path that cannot be written.

    Parameters
    ----------
    path : str or os.PathLike
    what : how the user named it, e.g. "-o", "--export", "export_field"
    formats : iterable of extensions ('.vtu', ...) the path may end in; None: any
    suffix_files : extensions of files written beside it (MEDIT's '.fra',
        '.perm'), checked as well

    Returns
    -------
    str
        The path as given.

    Raises
    ------
    OutputError
        Naming the path, what is wrong with it and what to do.
    """
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise OutputError(f"{what} {path!r}: must be a file path (a non-empty string)")
    path = os.fspath(path)
    where = f"{what} {path}"
    formats = None if formats is None else list(formats)
    ext = os.path.splitext(path.rstrip("/" + os.sep))[1].lower()
    _check_kind(path, where, f"give a file name inside it, e.g. "
                f"{os.path.join(path, 'out' + (formats[0] if formats else ext))}")
    if formats is not None and ext not in formats:
        name = os.path.basename(path) or "out"
        raise OutputError(f"{where}: unknown format {ext or '(no extension)'!r}; the file name must end in "
                          f"{' or '.join(formats)}, e.g. {os.path.splitext(name)[0] + formats[0]}")
    stem = os.path.splitext(path)[0]
    for s in suffix_files:
        _check_kind(stem + s, where, f"it is written beside {path}: move it away or choose another name")
    _check_folder(path, where)
    return path


def _check_kind(path: str, where: str, fix: str) -> None:
    """Refuse a path that is a folder or exists as anything but a regular file."""
    target = _target(path)
    if path.endswith(("/", os.sep)) or os.path.isdir(target):
        raise OutputError(f"{where}: {path} is a folder; {fix}")
    if os.path.exists(target) and not stat.S_ISREG(os.stat(target).st_mode):
        mode = os.stat(target).st_mode
        kind = "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file"
        raise OutputError(f"{where}: {path} is {kind}; SymFrames writes regular files only (whole, by renaming a "
                          "finished temporary file over the old one). Give a file path")


def _check_folder(path: str, where: str) -> None:
    """Refuse a folder that is missing, does not take a new file or is full."""
    target = _target(path)
    folder = os.path.dirname(os.path.abspath(target))
    if not os.path.isdir(folder):
        what = "is a file, not a folder" if os.path.exists(folder) else "does not exist"
        raise OutputError(f"{where}: the folder {folder} {what}; create it first or choose another path")
    try:
        fd, probe = tempfile.mkstemp(prefix=_PREFIX, suffix=".probe", dir=folder)
    except OSError as e:
        raise OutputError(f"{where}: " + os_error_message(path, e, " (checked before any work)")) from None
    os.close(fd)
    os.remove(probe)
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return
    if free < MIN_FREE_BYTES:
        raise OutputError(f"{where}: the disk holding {folder} is full ({free:,} bytes free); free some space or "
                          "write to another disk (checked before any work)")



def same_file(a, b) -> bool:
    """Whether two paths name one file: the same path after resolving
    symbolic links and ``..``, or (both existing) one file under two names
    (a hard link, a case-insensitive file system)."""
    ra, rb = os.path.realpath(os.fspath(a)), os.path.realpath(os.fspath(b))
    if os.path.normcase(ra) == os.path.normcase(rb):
        return True
    try:
        return os.path.samefile(ra, rb)
    except OSError:  # one of them does not exist (yet)
        return False


def check_distinct(outputs, inputs=()) -> None:
    """Refuse, before any work, an output that would replace an input or
    another output of the same run.

    Parameters
    ----------
    outputs : iterable of (what, path)
        every file the run writes, named as the user named it (e.g.
        ``("--hex", "x.vtu")``; a MEDIT export's ``.fra`` and ``.perm`` as
        ``("--export a.mesh", "a.fra")``)
    inputs : iterable of (what, path)
        every file the run reads (None paths are skipped)

    Raises
    ------
    OutputError
        naming both paths and how each was given
    """
    outs = [(w, os.fspath(p)) for w, p in outputs if p is not None]
    ins = [(w, os.fspath(p)) for w, p in inputs if p is not None]
    for what, path in outs:
        for iw, ip in ins:
            if same_file(path, ip):
                real = os.path.realpath(ip)
                link = "" if os.path.abspath(path) == os.path.abspath(ip) else f" (the same file, {real})"
                raise OutputError(f"{what} {path}: this is the {iw} input {ip}{link}; writing it would replace the "
                                  "input. Give the output another name (checked before any work; nothing was "
                                  "written)")
    for k, (what, path) in enumerate(outs):
        for w2, p2 in outs[:k]:
            if same_file(path, p2):
                raise OutputError(f"{w2} {p2} and {what} {path} name the same file: the second would replace the "
                                  "first. Give each output its own name (checked before any work; nothing was "
                                  "written)")
