"""Checks shared by every command for numbers, output paths, names and job sizes.

Config files go through :func:`ident.config.read_yaml` (bounded YAML); everything else a user
gives (a flag, a number inside a config, an output path, a name used in a path) goes through
the functions here, before any work starts:

* :func:`check_number` - finite, within a range (upper bounds where memory or time grow);
* :func:`check_output_dir` / :func:`check_output_file` - the place can be written (probed
  with a temporary file that is removed), is not a pseudo file system (``/proc``, ``/sys``,
  ``/dev``) and is of the right kind (a folder, a file);
* :func:`safe_component` - a user name turned into one path component (no ``..``, no ``/``);
* :class:`JobEstimate` and :func:`check_job` - the memory and time a job will take, refused
  above the ceilings ``IDENT_MAX_MEMORY_GB`` and ``IDENT_MAX_HOURS`` (environment variables;
  see ``docs/robustness.md``).

Every failure is a :class:`~ident.errors.ConfigError` naming the flag or key, the value, what
is allowed and how to change it.
"""

from __future__ import annotations

import math
import os
import re
import tempfile

# xml.etree: check_urdf_numbers checks EVERY attribute of EVERY element of a text about to be
# written, unknown extensions included; yourdfpy keeps only what it models (checked: UR5's
# <transmission>, <gazebo> blocks are gone after its round trip), and an inf it takes silently.
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from numbers import Integral, Real
from pathlib import Path
from typing import Any

from ident.config import read_text_input, short_repr
from ident.errors import ConfigError, ModelError

__all__ = [
    "DEFAULT_MAX_HOURS",
    "DEFAULT_MAX_MEMORY_GB",
    "DEFAULT_MEMORY_SHARE",
    "MAX_HOURS_ENV",
    "MAX_MEMORY_ENV",
    "JobEstimate",
    "ResourceLimitError",
    "check_job",
    "check_number",
    "check_output_dir",
    "check_output_file",
    "check_urdf_numbers",
    "default_max_memory_gb",
    "duration_text",
    "max_workers",
    "read_urdf_text",
    "refuse_dtd",
    "resource_ceilings",
    "safe_component",
]

MAX_MEMORY_ENV = "IDENT_MAX_MEMORY_GB"
MAX_HOURS_ENV = "IDENT_MAX_HOURS"
DEFAULT_MAX_HOURS = 24.0
# when IDENT_MAX_MEMORY_GB is unset, a job may plan to use a quarter of the physical memory,
# at most 4 GB: a shared machine keeps room for others, and a small file that declares
# gigabytes (a decompression bomb) is refused at once rather than read up to half the RAM
DEFAULT_MEMORY_SHARE = 0.25
DEFAULT_MAX_MEMORY_GB = 4.0
_PSEUDO_FILE_SYSTEMS = (Path("/proc"), Path("/sys"), Path("/dev"))
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
_MAX_COMPONENT = 80
MAX_URDF_BYTES = 64 << 20  # URDFs are text; meshes live in other files
_DTD = re.compile(r"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


class ResourceLimitError(ConfigError):
    """A job would need more memory or time than the configured ceiling."""


def check_number(
    value: Any,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = True,
    integer: bool = False,
    hint: str = "",
) -> Any:
    """Return ``value`` if it is a finite number in range, else raise one clear error.

    Parameters
    ----------
    value :
        The number to check (bools are refused: YAML reads ``yes`` as ``True``).
    name :
        The flag or key, as the user wrote it (``--samples``, ``emupso.maxiter``).
    low, high :
        Bounds; ``high`` is inclusive, ``low`` inclusive unless ``low_inclusive=False``.
    integer :
        Require an integer.
    hint :
        Appended to the message before its final period (how to change a limit).

    Raises
    ------
    ConfigError
        If ``value`` is not a (finite, integer when required) number within the bounds.
    """
    kind = "an integer" if integer else "a number"
    ok_type = isinstance(value, Integral) if integer else isinstance(value, Real)
    if isinstance(value, bool) or not ok_type:
        raise ConfigError(f"{name} = {short_repr(value)} must be {kind}{_tail(hint)}.")
    if not math.isfinite(float(value)):
        raise ConfigError(f"{name} = {value} must be a finite number{_tail(hint)}.")
    too_low = low is not None and (value < low if low_inclusive else value <= low)
    too_high = high is not None and value > high
    if too_low or too_high:
        lo = "" if low is None else (f">= {_fmt(low)}" if low_inclusive else f"> {_fmt(low)}")
        hi = "" if high is None else f"<= {_fmt(high)}"
        allowed = " and ".join(x for x in (lo, hi) if x)
        raise ConfigError(f"{name} = {_fmt(value)} must be {allowed}{_tail(hint)}.")
    return value


def _fmt(value: float) -> str:
    if isinstance(value, Integral) and abs(int(value)) < 10**21:
        return str(int(value))
    return f"{float(value):g}"


def _tail(hint: str) -> str:
    return f" {hint}" if hint else ""


def max_workers() -> int:
    """Worker processes a command may start: the CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _pseudo_file_system(path: Path) -> Path | None:
    resolved = path.resolve()
    for root in _PSEUDO_FILE_SYSTEMS:
        if resolved == root or root in resolved.parents:
            return root
    return None


def _existing_ancestor(path: Path) -> Path:
    current = path.absolute()
    while not current.exists() and current != current.parent:
        current = current.parent
    return current


def _probe_writable(folder: Path, name: str, path: Path) -> None:
    """Create and remove a temporary file in ``folder`` (the only reliable check)."""
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=".ident-probe-")
    except OSError as e:
        raise ConfigError(
            f"{name} {path}: cannot write in {folder} ({e.strerror}); choose another place."
        ) from e
    os.close(fd)
    os.unlink(tmp)


def check_output_dir(path: str | Path, name: str, *, must_be_new_or_empty: bool = False) -> Path:
    """Check that the folder ``path`` can be created (or exists) and written, without creating it.

    Parameters
    ----------
    path :
        The output folder.
    name :
        The flag or key naming it (``--out``).
    must_be_new_or_empty :
        Refuse an existing folder that holds anything (results are never overwritten).

    Raises
    ------
    ConfigError
        If ``path`` is a file, lies under ``/proc``, ``/sys`` or ``/dev``, is not empty when
        required, or its nearest existing parent is not a writable folder.
    """
    path = Path(path)
    root = _pseudo_file_system(path)
    if root is not None:
        raise ConfigError(
            f"{name} {path}: lies under {root}, which holds no files; choose a folder."
        )
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{name} {path}: exists and is not a folder; choose a folder.")
    if must_be_new_or_empty and path.is_dir() and any(path.iterdir()):
        raise ConfigError(
            f"{name} {path}: exists and is not empty; results are never overwritten, "
            "choose a new folder."
        )
    ancestor = _existing_ancestor(path)
    if not ancestor.is_dir():
        raise ConfigError(f"{name} {path}: {ancestor} is a file, not a folder; choose a folder.")
    _probe_writable(ancestor, name, path)
    return path


def check_output_file(path: str | Path, name: str, *, force_flag: str | None = None) -> Path:
    """Check that the file ``path`` can be written (its parents may be missing).

    ``force_flag`` (e.g. ``"--force"``): an existing file is refused unless the caller was
    given that flag (it passes None then); for a file a user edits by hand (a config), which
    is never overwritten silently, as results are never overwritten.

    Raises
    ------
    ConfigError
        If ``path`` is a folder, lies under ``/proc``, ``/sys`` or ``/dev``, exists and
        ``force_flag`` is given, or its nearest existing parent is not a writable folder.
    """
    path = Path(path)
    root = _pseudo_file_system(path)
    if root is not None:
        raise ConfigError(f"{name} {path}: lies under {root}; choose a regular file.")
    if path.is_dir():
        raise ConfigError(f"{name} {path}: is a folder; give a file name.")
    if path.exists() and not path.is_file():
        raise ConfigError(f"{name} {path}: is not a regular file; give a file name.")
    if force_flag is not None and path.exists():
        raise ConfigError(
            f"{name} {path}: exists and is not overwritten (it may hold your edits); choose "
            f"a new file name, or add {force_flag} to replace it."
        )
    ancestor = _existing_ancestor(path.parent)
    if not ancestor.is_dir():
        raise ConfigError(f"{name} {path}: {ancestor} is a file, not a folder.")
    _probe_writable(ancestor, name, path)
    return path


def read_urdf_text(path: str | Path) -> str:
    """Read a URDF as UTF-8 text and refuse what not every parser of ``ident`` reads alike.

    A document type declaration (``<!DOCTYPE ...>``, ``<!ENTITY ...>``) is refused: Pinocchio
    (urdfdom) and Python's XML parser disagree on entities, so a model could load in one
    step and fail (or differ) in a later one, after the work is done.

    Raises
    ------
    ModelError
        Missing, binary, non-UTF-8 or oversized file, or a DTD declaration.
    """
    path = Path(path)
    try:
        text = read_text_input(path, what="URDF", max_bytes=MAX_URDF_BYTES)
    except ConfigError as e:
        raise ModelError(str(e)) from e
    refuse_dtd(text, path)
    return text


def refuse_dtd(text: str, where: str | Path) -> None:
    """Refuse URDF text with a document type declaration (``<!DOCTYPE>``, ``<!ENTITY>``).

    Pinocchio (urdfdom) and Python's XML parser disagree on entities: the one rule every
    reader of URDF text in ``ident`` applies.

    Raises
    ------
    ModelError
        Naming ``where`` and the line of the declaration.
    """
    match = _DTD.search(text)
    if match:
        line = text[: match.start()].count("\n") + 1
        raise ModelError(
            f"{where}: line {line}: a <!{match.group(1).upper()}> declaration; URDFs "
            "with a DTD or entities are not supported, write the values out."
        )


def check_urdf_numbers(text: str, source: str) -> None:
    """Refuse URDF text holding a non-finite number (``inf``, ``nan``) in any attribute.

    Pinocchio refuses such a file when it loads it, so a writer checks its output first.

    Raises
    ------
    ModelError
        Naming the element, its ``name`` and the attribute.
    """
    for element in ET.fromstring(text).iter():
        for key, value in element.attrib.items():
            for word in value.split():
                try:
                    number = float(word)
                except ValueError:
                    continue
                if not math.isfinite(number):
                    owner = element.get("name") or element.tag
                    raise ModelError(
                        f"{source}: the URDF would hold {key}={value!r} in <{element.tag}> "
                        f"({owner}); give finite values (limits, inertials, origins)."
                    )


def safe_component(name: str, *, default: str = "run") -> str:
    """``name`` as one path component: ``[A-Za-z0-9._-]``, no leading dot, at most 80 chars.

    ``"../../x"`` becomes ``"x"``, ``"/etc/passwd"`` becomes ``"etc_passwd"``; a name with
    nothing left becomes ``default``.
    """
    cleaned = _UNSAFE.sub("_", str(name)).lstrip("._-")[:_MAX_COMPONENT].rstrip(".")
    return cleaned or default


@dataclass(frozen=True, slots=True)
class JobEstimate:
    """Rough peak memory and wall time of a job, printed before it starts.

    Attributes
    ----------
    what :
        The job (``"bench: 6480 runs"``).
    memory_bytes :
        Peak memory [bytes].
    seconds :
        Wall time [s] (an order of magnitude: the estimate uses a fixed cost per unit).
    worst_seconds :
        Wall time [s] when a conditional step runs too (``worst_case`` says which); 0: none.
    worst_case :
        The conditional step (``"if the design is retried at a wider margin"``).
    """

    what: str
    memory_bytes: float
    seconds: float
    worst_seconds: float = 0.0
    worst_case: str = ""

    def describe(self) -> str:
        """One line: ``what: about 1.2 GB of memory and 3.4 min`` (``, up to 6.8 min if
        ...`` when a conditional step can add time)."""
        memory, time = _bytes(self.memory_bytes), duration_text(self.seconds)
        line = f"{self.what}: about {memory} of memory and {time}"
        if self.worst_seconds > self.seconds:
            line += f", up to {duration_text(self.worst_seconds)} {self.worst_case}"
        return line


def _bytes(n: float) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.0f} B"


def duration_text(s: float) -> str:
    """A duration [s] as a person reads it: ``42 s``, ``3.4 min``, ``1.2 h``, ``2 days``."""
    for unit, scale in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s:.2g} s"


def _physical_memory() -> float:
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 8e9


def _env_positive(name: str, default: float) -> float:
    text = os.environ.get(name)
    if text is None or not text.strip():
        return default
    try:
        value = float(text)
    except ValueError as e:
        raise ConfigError(f"{name}={short_repr(text)} must be a number.") from e
    return float(check_number(value, name, low=0.0, low_inclusive=False))


def default_max_memory_gb() -> float:
    """The memory ceiling [GB] when ``IDENT_MAX_MEMORY_GB`` is unset: a quarter of the
    physical memory, at most :data:`DEFAULT_MAX_MEMORY_GB` (4 GB)."""
    return min(DEFAULT_MAX_MEMORY_GB, DEFAULT_MEMORY_SHARE * _physical_memory() / 1e9)


def resource_ceilings() -> tuple[float, float]:
    """(memory [bytes], time [s]) a job may plan to use.

    ``IDENT_MAX_MEMORY_GB`` (default: :func:`default_max_memory_gb`) and ``IDENT_MAX_HOURS``
    (default :data:`DEFAULT_MAX_HOURS`) raise or lower them.
    """
    memory_gb = _env_positive(MAX_MEMORY_ENV, default_max_memory_gb())
    hours = _env_positive(MAX_HOURS_ENV, DEFAULT_MAX_HOURS)
    return memory_gb * 1e9, hours * 3600.0


def check_job(estimate: JobEstimate) -> JobEstimate:
    """Refuse a job above the memory or time ceiling (:func:`resource_ceilings`).

    Raises
    ------
    ResourceLimitError
        Saying the estimate, the ceiling and the environment variable that raises it.
    """
    memory, seconds = resource_ceilings()
    if estimate.memory_bytes > memory:
        unset = not os.environ.get(MAX_MEMORY_ENV, "").strip()
        default = " (the default: a quarter of the physical memory, at most 4 GB)" if unset else ""
        raise ResourceLimitError(
            f"{estimate.describe()}, above the memory ceiling of {_bytes(memory)}{default}; "
            f"make the job smaller, or raise the ceiling with {MAX_MEMORY_ENV}=<GB> if the "
            "machine has it."
        )
    if estimate.seconds > seconds:
        raise ResourceLimitError(
            f"{estimate.describe()}, above the time ceiling of {duration_text(seconds)}; make the "
            f"job smaller, or raise the ceiling with {MAX_HOURS_ENV}=<hours>."
        )
    return estimate
