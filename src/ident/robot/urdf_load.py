"""From URDF text to a Pinocchio model of the chain to identify.

Everything :meth:`ident.model.Robot.from_urdf` does to a file before the robot exists: parse
the XML with one-line errors, rewrite continuous joints as revolute ones, check the inertials of
the links that move, choose the chain (``base_link`` / ``tip_link`` and locked joints) and build
Pinocchio's reduced model. The same rules serve every command (``verify``, ``run``,
``identify``, ``replay``), so they accept and reject the same robots.
"""

from __future__ import annotations

import contextlib
import difflib
import os
import sys
import tempfile

# xml.etree: this is the robot loader's validation of the raw text (bad limits, loops, inertials,
# each error naming the joint and the field) and the continuous->revolute rewrite of the user's
# text handed to Pinocchio; yourdfpy's reader cannot give the project's named errors: a non-number
# raises a bare ValueError ("could not convert string to float: 'abc'", no joint, no field; the
# same for xacro's "${-pi}"), and URDF.load re-parses malformed XML with lxml recover=True
# (checked: a truncated file loads) and expands DTD entities (checked), which the project refuses;
# for the rewrite: yourdfpy's round trip drops what it does not model (checked on example-robot-
# data's UR5: its 6 <transmission>, 8 <gazebo> blocks and 24 comments are gone) and rewrites
# numbers (rpy "0 0 0" -> "0.0 -0.0 0.0").
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.errors import ModelError
from ident.inputs import MAX_URDF_BYTES, read_urdf_text, refuse_dtd
from ident.robot.inertia import consistency_problems, parameters_from_com, urdf_inertia_tensor

__all__ = [
    "URDF_INERTIA_RTOL",
    "build_model",
    "chain_locks",
    "check_inertials",
    "check_tree",
    "checked_limits",
    "continuous_as_revolute",
    "expand_xacro",
    "lock_values",
    "locked_model",
    "model_from_text",
    "moving_links",
    "needs_xacro",
    "parse_xml",
    "prepare_urdf",
    "PreparedURDF",
    "suggested_locks",
    "urdf_file_text",
]

#: Relative tolerance of the inertial consistency check of URDF links (to the largest principal
#: moment): URDF files print inertias with a few significant digits, so a link on the boundary
#: (a thin rod or plate, I1 + I2 = I3) may violate it by round-off; 1e-6 accepts that, not more.
URDF_INERTIA_RTOL = 1e-6


@contextlib.contextmanager
def _captured_stderr() -> Iterator[Callable[[], list[str]]]:
    """Capture what C++ libraries write to file descriptor 2 (urdfdom's parse errors)."""
    captured: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real stderr (e.g. some embedded interpreters)
        yield lambda: captured
        return
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lambda: captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.extend(sink.read().decode("utf-8", "replace").splitlines())


def urdf_file_text(
    path: Path, package_dirs: Sequence[str | os.PathLike[str]] = (), where: str | None = None
) -> str:
    """The URDF text of a robot file: read (UTF-8, bounded, no DTD), expanded by xacro when it
    is a ``.xacro`` file or still holds xacro (:func:`expand_xacro`)."""
    where = str(path) if where is None else where
    text = read_urdf_text(path)
    if needs_xacro(path, text):
        text = expand_xacro(path, package_dirs, where)
        if len(text) > MAX_URDF_BYTES:
            raise ModelError(
                f"{where}: xacro expands the file to {len(text) >> 20} MB of URDF, more than "
                f"{MAX_URDF_BYTES >> 20} MB; check its macros."
            )
        refuse_dtd(text, where)  # an included file may declare one
    return text


_XACRO_NAMESPACE = "{http://www.ros.org/wiki/xacro}"


def needs_xacro(path: os.PathLike[str] | str, text: str) -> bool:
    """True for a ``.xacro`` file, or URDF text that still holds xacro outside its comments:
    a ``<xacro:...>`` element, or ``${...}`` / ``$(...)`` in an attribute (vendors' URDFs
    keep commented-out xacro; text that is not XML is left to the URDF parser's error)."""
    if str(path).lower().endswith(".xacro"):
        return True
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return False
    for element in root.iter():
        if isinstance(element.tag, str) and element.tag.startswith(_XACRO_NAMESPACE):
            return True
        if any("${" in v or "$(" in v for v in element.attrib.values()):
            return True
    return False


@contextlib.contextmanager
def _find_in(package_dirs: Sequence[str | os.PathLike[str]]) -> Iterator[list[str]]:
    """Serve xacro's ``$(find pkg)`` from ``package_dirs`` (folders that hold the package
    folders, as for ``package://`` URIs) instead of a ROS installation, for the ``with``; the
    list it yields receives the packages not found (xacro wraps the exception)."""
    from xacro import substitution_args

    missing: list[str] = []

    def find(package: str) -> str:
        for folder in package_dirs:
            candidate = Path(folder) / package
            if candidate.is_dir():
                return str(candidate.resolve())
        missing.append(package)
        raise LookupError(package)

    saved = substitution_args._eval_find
    saved_eval = substitution_args._eval_dict.get("find")
    substitution_args._eval_find = find
    substitution_args._eval_dict["find"] = find
    try:
        yield missing
    finally:
        substitution_args._eval_find = saved
        substitution_args._eval_dict["find"] = saved_eval


def expand_xacro(path: Path, package_dirs: Sequence[str | os.PathLike[str]], where: str) -> str:
    """The URDF text of a xacro file, expanded with the ``xacro`` package (no ROS needed:
    ``$(find pkg)`` is looked up in ``package_dirs``).

    Raises
    ------
    ModelError
        One line naming the file and the command that expands it by hand, when ``xacro`` is
        not installed or cannot expand the file.
    """
    name = Path(path).name
    # never the input's own name: the shell would empty it before xacro reads it
    stem = name.removesuffix(".xacro") if name.endswith(".xacro") else f"{Path(name).stem}.expanded"
    by_hand = f"xacro {name} > {stem.removesuffix('.urdf')}.urdf"
    try:
        import xacro
    except ImportError as e:
        raise ModelError(
            f"{where}: the file is xacro and the xacro package is not installed; install it "
            f"(pip install xacro) or expand the file yourself: {by_hand}"
        ) from e
    missing: list[str] = []
    try:
        with _find_in(package_dirs) as missing, contextlib.redirect_stdout(sys.stderr):
            document = xacro.process_file(str(Path(path).resolve()))
        return str(document.toxml())
    except Exception as e:  # noqa: BLE001 - xacro raises anything (XacroException, NameError)
        if missing:
            dirs = ", ".join(str(d) for d in package_dirs) or "none given"
            raise ModelError(
                f"{where}: xacro's $(find {missing[0]}): no folder {missing[0]!r} in the "
                f"package folders ({dirs}); give the folder that holds it with "
                "robot.package_dirs (--package-dir DIR), or expand the file yourself: "
                f"{by_hand}"
            ) from e
        reason = " ".join(str(e).split()) or type(e).__name__
        raise ModelError(
            f"{where}: xacro cannot expand the file ({reason}); fix it or expand it yourself "
            f"and give the URDF: {by_hand}"
        ) from e


def parse_xml(text: str, where: str) -> ET.Element:
    """Parse URDF text into its ``<robot>`` element, with one-line ModelErrors."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise ModelError(f"{where}: malformed URDF XML ({e}); fix the file.") from e
    if root.tag != "robot":
        raise ModelError(f"{where}: the root element is <{root.tag}>, not <robot>; not a URDF.")
    return root


def check_inertials(root: ET.Element, where: str, links: set[str] | None = None) -> None:
    """Raise a ModelError naming the first link whose ``<inertial>`` is physically impossible.

    A link without ``<inertial>`` (or with mass and inertia all zero) is massless and accepted.
    The URDF inertia is about the centre of mass, so the check needs no frame change.
    ``links``: check only these links (those that enter the chain's dynamics, see
    :func:`moving_links`); ``None`` checks every link.
    """
    for link in root.findall("link"):
        name = link.get("name", "?")
        inertial = link.find("inertial")
        if inertial is None or (links is not None and name not in links):
            continue
        mass_element, inertia_element = inertial.find("mass"), inertial.find("inertia")
        try:
            mass = float(mass_element.get("value", "0")) if mass_element is not None else 0.0
            tensor = urdf_inertia_tensor(
                inertia_element.attrib if inertia_element is not None else None
            )
        except ValueError as e:
            raise ModelError(
                f"{where}: link {name!r}: the <inertial> has a value that is not a number ({e}); "
                "fix the file."
            ) from e
        if mass == 0.0 and not tensor.any():
            continue
        problems = consistency_problems(
            parameters_from_com(mass, np.zeros(3), tensor), rtol=URDF_INERTIA_RTOL
        )
        if problems:
            raise ModelError(
                f"{where}: link {name!r}: the <inertial> is physically impossible: {problems[0]}; "
                "fix the link's mass (> 0) and its inertia about the centre of mass "
                "(positive principal moments with I1 + I2 >= I3), or set "
                "robot.inertia_check: false to load the file anyway."
            )


_MOVING_TYPES = ("revolute", "prismatic", "continuous")


def _limit_value(limit: ET.Element, key: str, joint: str, where: str) -> float | None:
    """The ``<limit key=...>`` of a joint as a finite float, ``None`` when absent.

    Raises a ModelError naming the file, the joint and the attribute for text that is not a
    finite number, and for a negative velocity or effort.
    """
    text = limit.get(key)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value):
        fix = (
            'give the limit in rad (m for a prismatic joint), or make the joint type="continuous" '
            "if it turns without end"
            if key in ("lower", "upper")
            else f"give the joint's {key} limit as a positive number, or 0 if you do not know it"
        )
        raise ModelError(
            f'{where}: joint {joint!r}: <limit {key}="{text}"> is not a finite number; {fix}.'
        )
    if key in ("velocity", "effort") and value < 0.0:
        raise ModelError(
            f'{where}: joint {joint!r}: <limit {key}="{text}"> is negative; give the {key} '
            "limit as a positive magnitude."
        )
    return value


def checked_limits(root: ET.Element, where: str) -> tuple[dict[tuple[str, str], str], bool]:
    """Check the ``<limit>`` of every moving joint and say which limits the URDF leaves unknown.

    A position range with ``lower > upper`` (swapped) and a limit that is not a finite number
    are errors. A missing ``<limit>`` or attribute, a velocity or effort of 0 and an empty range
    (``lower == upper``, both 0 included) are unknown: Pinocchio would read them as 0. Missing
    ``effort`` / ``velocity`` attributes (and a missing ``<limit>``) are added as ``0`` to
    ``root`` so that Pinocchio parses the joint; a position range with one side missing loses
    the other (both unknown). A continuous joint's position is unlimited, not unknown.

    Parameters
    ----------
    root :
        The parsed ``<robot>`` element, completed in place.
    where :
        The file, for the messages.

    Returns
    -------
    unknown, changed :
        ``(kind, joint) -> reason`` (kind ``position``, ``velocity`` or ``torque``; reason
        ``"the URDF gives effort 0"``), and whether ``root`` was completed.

    Raises
    ------
    ModelError
        Naming the file, the joint and the attribute, for a swapped range, a value that is not
        a finite number, or a negative velocity or effort.
    """
    unknown: dict[tuple[str, str], str] = {}
    changed = False
    for joint in root.findall("joint"):
        kind, name = joint.get("type"), joint.get("name", "?")
        if kind not in _MOVING_TYPES:
            continue
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit")
            changed = True
        for key, what in (("velocity", "velocity"), ("effort", "torque")):
            value = _limit_value(limit, key, name, where)
            if value is None:
                unknown[what, name] = f"the URDF gives no {key} limit"
                limit.set(key, "0")
                changed = True
            elif value == 0.0:
                unknown[what, name] = f"the URDF gives {key} 0"
        if kind != "continuous":
            reason, trimmed = _position_unknown(limit, name, where)
            changed |= trimmed
            if reason:
                unknown["position", name] = reason
    return unknown, changed


def _position_unknown(limit: ET.Element, joint: str, where: str) -> tuple[str, bool]:
    """Why the ``lower``/``upper`` of a revolute or prismatic joint are unknown (``""``: known),
    and whether a one-sided range was removed (Pinocchio would read the missing side as 0)."""
    lower = _limit_value(limit, "lower", joint, where)
    upper = _limit_value(limit, "upper", joint, where)
    if lower is not None and upper is not None:
        if lower > upper:
            raise ModelError(
                f'{where}: joint {joint!r}: <limit lower="{limit.get("lower")}" '
                f'upper="{limit.get("upper")}">: lower is above upper (swapped?); give '
                "lower < upper."
            )
        if lower == upper:
            return f"the URDF gives lower = upper = {lower:g} (an empty range)", False
        return "", False
    if lower is None and upper is None:
        return "the URDF gives no position limit", False
    missing = "upper" if upper is None else "lower"
    for key in ("lower", "upper"):
        limit.attrib.pop(key, None)
    return f"the URDF gives no {missing} position limit", True


def continuous_as_revolute(root: ET.Element, text: str) -> tuple[str, tuple[str, ...]]:
    """Rewrite the continuous joints of a URDF as revolute joints without position limit.

    Pinocchio models a continuous joint with the unit complex number ``(cos q, sin q)``
    (nq = 2, nv = 1); a revolute joint about the same axis with the angle ``q`` has the same
    kinematics and dynamics at the corresponding state, with nq = nv = 1 as the chain needs.
    The ``<limit>`` keeps its effort and velocity and loses any lower/upper bound (Pinocchio
    then reads an empty range, which :class:`Robot` treats as unknown).

    Parameters
    ----------
    root :
        The parsed ``<robot>`` element (modified in place when there is a continuous joint).
    text :
        The URDF text of ``root``.

    Returns
    -------
    text, names :
        The URDF text (``text`` itself when there is no continuous joint) and the names of the
        rewritten joints, in file order.
    """
    names = []
    for joint in root.findall("joint"):
        if joint.get("type") != "continuous":
            continue
        names.append(joint.get("name", "?"))
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit")
        for key in ("lower", "upper"):
            limit.attrib.pop(key, None)
        for key in ("effort", "velocity"):  # urdfdom needs both; 0 means unknown here
            limit.set(key, limit.get(key, "0"))
    if not names:
        return text, ()
    return ET.tostring(root, encoding="unicode"), tuple(names)


@dataclass(frozen=True)
class PreparedURDF:
    """A URDF text as Pinocchio will read it (see :func:`prepare_urdf`).

    Attributes
    ----------
    root :
        The parsed ``<robot>`` element, rewritten like ``text``.
    text :
        The text for Pinocchio: continuous joints as revolute ones, missing velocity and
        effort limits as 0 (the input text itself when nothing changed).
    continuous :
        The continuous joints, in file order.
    unknown :
        ``(kind, joint) -> reason`` of the limits the file leaves unknown
        (:func:`checked_limits`).
    """

    root: ET.Element
    text: str
    continuous: tuple[str, ...]
    unknown: dict[tuple[str, str], str]


def prepare_urdf(text: str, where: str) -> PreparedURDF:
    """Parse, check and rewrite a URDF text for Pinocchio: the one way every reader of a URDF
    (the robot, the collision geometry) turns the file into a model.

    Raises
    ------
    ModelError
        Naming the file: malformed XML, a kinematic loop (:func:`check_tree`), a bad limit
        (:func:`checked_limits`).
    """
    root = parse_xml(text, where)
    check_tree(root, where)
    unknown, completed = checked_limits(root, where)
    revolute_text, continuous = continuous_as_revolute(root, text)
    if completed and not continuous:
        revolute_text = ET.tostring(root, encoding="unicode")
    return PreparedURDF(root, revolute_text, continuous, unknown)


def check_tree(root: ET.Element, where: str) -> None:
    """Raise a ModelError naming the link that is the child of two joints (a kinematic loop).

    Pinocchio builds a tree; a second joint into a link would be reported as a missing body.
    """
    parent_joint: dict[str, str] = {}
    for joint in root.findall("joint"):
        child = joint.find("child")
        link = None if child is None else child.get("link")
        if link is None:
            continue
        name = joint.get("name", "?")
        if link in parent_joint:
            raise ModelError(
                f"{where}: link {link!r} is the child of joints {parent_joint[link]!r} and "
                f"{name!r} (a kinematic loop); ident reads tree-shaped URDFs: remove one of "
                "the joints."
            )
        parent_joint[link] = name


def lock_values(
    model: pin.Model, lock_joints: Mapping[str, float] | Sequence[str] | None, where: str
) -> dict[str, float]:
    """Joint name -> locked position, checked against the model's joints and limits."""
    if lock_joints is None:
        return {}
    if isinstance(lock_joints, str):
        lock_joints = [lock_joints]
    if isinstance(lock_joints, Mapping):
        values = {str(k): float(v) for k, v in lock_joints.items()}
    else:
        values = {}
        for name in lock_joints:
            if name in values:
                raise ModelError(f"{where}: joint {name!r} is locked twice; lock it once.")
            values[name] = 0.0
    names = list(model.names[1:])
    for name, value in values.items():
        if not model.existJointName(name):
            close = difflib.get_close_matches(name, names, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ModelError(
                f"{where}: cannot lock joint {name!r}: no such joint; {hint}"
                f"joints: {', '.join(names)}."
            )
        joint = model.joints[model.getJointId(name)]
        if joint.nq != 1:
            raise ModelError(
                f"{where}: cannot lock joint {name!r}: it has nq={joint.nq}; only 1-DoF joints "
                "can be locked at a value."
            )
        lower = float(model.lowerPositionLimit[joint.idx_q])
        upper = float(model.upperPositionLimit[joint.idx_q])
        if not np.isfinite(value):
            raise ModelError(f"{where}: joint {name!r} locked at {value}; give a finite value.")
        if upper > lower and not lower <= value <= upper:
            raise ModelError(
                f"{where}: joint {name!r} locked at {value:g}, outside its limits "
                f"[{lower:g}, {upper:g}]; give a value within them."
            )
    return values


def locked_model(model: pin.Model, locked: Mapping[str, float], where: str) -> pin.Model:
    """Pinocchio's reduced model with the joints ``locked`` held at their values.

    The links behind a locked joint are fused into the body of the nearest moving joint above
    it (``pin.buildReducedModel``), as are links behind fixed joints. ``model`` itself when
    nothing is locked.

    Raises
    ------
    ModelError
        If Pinocchio cannot lock the joints (e.g. a link and a joint share a name).
    """
    if not locked:
        return model
    if set(locked) >= {str(n) for n in model.names[1:]}:  # an empty chain: nothing to identify
        raise ModelError(
            f"{where}: every joint is locked ({', '.join(locked)}); no joint is left to "
            "identify: lock fewer joints (--lock / robot.lock)."
        )
    reference = pin.neutral(model)
    for name, value in locked.items():
        reference[model.joints[model.getJointId(name)].idx_q] = value
    ids = [model.getJointId(name) for name in locked]
    try:
        return pin.buildReducedModel(model, ids, reference)
    except (RuntimeError, ValueError) as e:
        raise ModelError(
            f"{where}: Pinocchio cannot lock {', '.join(locked)} in this file ({e}); "
            "rename the links or joints that share a name."
        ) from e


def suggested_locks(model: pin.Model) -> tuple[str, ...]:
    """Joints to lock to make a branched model a serial chain, base to tip.

    Walks from the base; where the tree branches it follows the deepest branch (the first of
    equally deep ones) and suggests locking the others, except that equally deep single
    joints at the tip of a chain (gripper fingers) are all suggested. Empty for a serial model.
    """
    children: dict[int, list[int]] = {i: [] for i in range(model.njoints)}
    for i in range(1, model.njoints):
        children[int(model.parents[i])].append(i)

    def depth(i: int) -> int:
        return 1 + max((depth(k) for k in children[i]), default=0)

    def subtree(i: int) -> list[int]:
        return [i] + [j for k in children[i] for j in subtree(k)]

    locks: list[int] = []
    node = 0
    while children[node]:
        kids = children[node]
        if len(kids) == 1:
            node = kids[0]
            continue
        depths = [depth(k) for k in kids]
        if node != 0 and max(depths) == 1:
            locks.extend(kids)
            break
        chosen = kids[depths.index(max(depths))]
        locks.extend(j for k in kids if k != chosen for j in subtree(k))
        node = chosen
    return tuple(model.names[i] for i in sorted(locks))


def build_model(text: str, where: str) -> pin.Model:
    """Parse URDF text with Pinocchio, turning parser failures into one-line ModelErrors."""
    parse_xml(text, where)
    with _captured_stderr() as messages:
        try:
            model = pin.buildModelFromXML(text)
        except (RuntimeError, ValueError) as e:
            error: Exception | None = e
        else:
            error = None
    if error is not None:
        # urdfdom explains the problem on stderr ("child link [x] of joint [j] not found")
        details = [line.strip() for line in messages() if line.strip().startswith("Error:")]
        reason = details[0].removeprefix("Error:").strip() if details else str(error).strip()
        raise ModelError(
            f"{where}: Pinocchio cannot parse the URDF ({reason.splitlines()[0]}); fix the file."
        ) from error
    if model.njoints < 2:
        raise ModelError(f"{where}: the URDF has no moving joint; a serial arm is needed.")
    return model


def model_from_text(text: str, where: str) -> pin.Model:
    """Pinocchio's model of a URDF text, read as :meth:`ident.Robot.from_urdf` reads it
    (:func:`prepare_urdf`: continuous joints revolute, missing limits 0; the full tree, no
    lock)."""
    return build_model(prepare_urdf(text, where).text, where)


def _body_joint(model: pin.Model, link: str, key: str, where: str) -> int:
    """The joint that carries URDF link ``link`` (0: the link is fixed to the world)."""
    if not model.existBodyName(link):
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        close = difflib.get_close_matches(link, links, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ModelError(
            f"{where}: robot.{key} = {link!r} is not a link of the URDF; {hint}"
            f"links: {', '.join(links)}."
        )
    return int(model.frames[model.getBodyId(link)].parentJoint)


def chain_locks(
    model: pin.Model, base_link: str | None, tip_link: str | None, where: str
) -> tuple[str, ...]:
    """Joints outside the chain from ``base_link`` to ``tip_link``, to be locked.

    The chain is the joints on the path from ``base_link`` down to ``tip_link``. Without
    ``tip_link`` it is every joint below ``base_link`` (the subtree must then be serial);
    without ``base_link`` the path starts at the URDF's root. Everything else (a mobile base or
    torso above ``base_link``, other arms, grippers below or beside the path) is locked.

    Raises
    ------
    ModelError
        For an unknown link, or a ``tip_link`` that is not below ``base_link``.
    """
    if base_link is None and tip_link is None:
        return ()
    base_joint = 0 if base_link is None else _body_joint(model, base_link, "base_link", where)
    above = set(int(j) for j in model.supports[base_joint])  # joints moving base_link
    if tip_link is None:
        chain = {j for j in range(1, model.njoints) if base_joint in set(model.supports[j])} - above
    else:
        tip_joint = _body_joint(model, tip_link, "tip_link", where)
        support = [int(j) for j in model.supports[tip_joint]]
        if not above <= set(support):
            raise ModelError(
                f"{where}: robot.tip_link {tip_link!r} is not below robot.base_link "
                f"{base_link!r}; choose a tip link in the subtree of the base link."
            )
        chain = set(support) - above
    if not chain:
        raise ModelError(
            f"{where}: no joint moves between robot.base_link {base_link!r} and robot.tip_link "
            f"{tip_link!r}; choose links with at least one joint between them."
        )
    return tuple(model.names[j] for j in range(1, model.njoints) if j not in chain)


def moving_links(model: pin.Model, locked: Mapping[str, float] | Sequence[str]) -> set[str]:
    """URDF links that move when the joints ``locked`` are held: they enter the dynamics.

    A link whose supporting joints are all locked (or that is fixed to the world) never moves,
    so its inertial cannot change the torques of the chain and is not checked.
    """
    held = set(locked)
    out = set()
    for frame in model.frames:
        if frame.type != pin.FrameType.BODY:
            continue
        support = [int(j) for j in model.supports[frame.parentJoint]][1:]
        if any(model.names[j] not in held for j in support):
            out.add(frame.name)
    return out
