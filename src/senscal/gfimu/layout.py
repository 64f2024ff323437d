"""Accelerometer-array layouts and the rigid-body kinematic solve.

A single-axis accelerometer at position ``r_i`` (body frame, m) with unit
sensitive direction ``n_i`` reads

    a_i = n_i . (f_O + alpha x r_i + W r_i),   W = w w^T - |w|^2 I,

which is linear in the 12 kinematic unknowns (specific force ``f_O`` at the
array origin, angular acceleration ``alpha`` and the six distinct entries of
the symmetric matrix ``W``).  One design matrix serves every sample.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5), eq. (1)-(4) (seed 001).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import DegenerateGeometryError, FileFormatError, InputError
from senscal.io.guard import check_output, write_text
from senscal.io.sidefiles import read_text

__all__ = ["Layout", "KinematicSolution", "paper_layout", "read_layout", "solve_kinematics",
           "UNKNOWNS", "MAX_CONDITION"]

#: Order of the 12 kinematic unknowns in :attr:`KinematicSolution.x`.
UNKNOWNS = ("f_x", "f_y", "f_z", "alpha_x", "alpha_y", "alpha_z",
            "W_xx", "W_yy", "W_zz", "W_xy", "W_xz", "W_yz")

#: Scale-free condition number beyond which a layout is refused: the solve
#: would amplify rounding and noise by more than 1e8.
MAX_CONDITION = 1e8


@dataclass(frozen=True)
class Layout(ResultMixin):
    """Positions and sensitive directions of an array's single-axis channels.

    Parameters
    ----------
    names : tuple of str
        Channel names, one per single-axis accelerometer.
    positions : ndarray, shape (M, 3)
        Sensor positions in the body frame, m.
    directions : ndarray, shape (M, 3)
        Sensitive directions (normalised on construction, dimensionless).
    """

    names: tuple[str, ...]
    positions: np.ndarray
    directions: np.ndarray
    design: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        pos = np.array(self.positions, dtype=float).reshape(-1, 3) if np.size(self.positions) else np.zeros((0, 3))
        dirs = np.array(self.directions, dtype=float).reshape(-1, 3) if np.size(self.directions) else np.zeros((0, 3))
        if not (len(names) == pos.shape[0] == dirs.shape[0]):
            raise InputError(f"layout has {len(names)} names, {pos.shape[0]} positions and {dirs.shape[0]} directions; "
                             "give one row per channel")
        if len(set(names)) != len(names):
            raise InputError("layout channel names must be unique")
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(dirs))):
            raise InputError("layout positions and directions must be finite numbers")
        norm = np.linalg.norm(dirs, axis=1)
        if np.any(norm < 1e-12):
            bad = names[int(np.argmin(norm))]
            raise InputError(f"channel '{bad}' has a zero sensitive direction; give nx ny nz of unit length")
        dirs = dirs / norm[:, None]
        pos.setflags(write=False)
        dirs.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "directions", dirs)
        object.__setattr__(self, "design", design_matrix(pos, dirs))

    @property
    def n_channels(self) -> int:
        return len(self.names)


def design_matrix(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Rows ``d a_i / d x`` for the 12 unknowns in :data:`UNKNOWNS` order.

    Parameters
    ----------
    positions, directions : ndarray, shape (M, 3)
        Positions (m) and unit sensitive directions.

    Returns
    -------
    ndarray, shape (M, 12)
        Columns 0-2 dimensionless, 3-11 in m.
    """
    r = np.asarray(positions, float)
    n = np.asarray(directions, float)
    # n . (alpha x r) = alpha . (r x n)
    rxn = np.cross(r, n)
    diag = n * r
    off = np.stack([n[:, 0] * r[:, 1] + n[:, 1] * r[:, 0],
                    n[:, 0] * r[:, 2] + n[:, 2] * r[:, 0],
                    n[:, 1] * r[:, 2] + n[:, 2] * r[:, 1]], axis=1)
    return np.concatenate([n, rxn, diag, off], axis=1)


def paper_layout(distance: float = 0.04) -> Layout:
    """The paper's array: four three-axis accelerometers A1..A4.

    A1 at the origin, A2, A3, A4 at ``distance`` along x, y, z, every chip's
    axes parallel to the body axes; channels ``a1x, a1y, a1z, ..., a4z``.

    Parameters
    ----------
    distance : float
        Mounting distance L, m (the paper uses 0.04 m).

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), section 1.2; METHODS.md 2b.
    """
    if not np.isfinite(distance) or distance <= 0:
        raise InputError(f"mounting distance must be a positive length in m, got {distance!r}")
    origins = np.array([[0, 0, 0], [distance, 0, 0], [0, distance, 0], [0, 0, distance]], float)
    names, pos, dirs = [], [], []
    for k in range(4):
        for j, ax in enumerate("xyz"):
            names.append(f"a{k + 1}{ax}")
            pos.append(origins[k])
            dirs.append(np.eye(3)[j])
    return Layout(tuple(names), np.array(pos), np.array(dirs))


_LAYOUT_COLUMNS = ("name", "x", "y", "z", "nx", "ny", "nz")


def read_layout(path: str | Path) -> Layout:
    """Read a layout table (CSV with columns ``name, x, y, z, nx, ny, nz``).

    Positions in m, directions as any non-zero vector (normalised).
    """
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(f"layout file {path} does not exist")
    text = read_text(path, "layout file")  # one-line errors for unreadable / non-UTF-8 files
    rows = [r for r in csv.reader(line for line in io.StringIO(text, newline="")
                                  if line.strip() and not line.lstrip().startswith("#"))]
    if not rows:
        raise FileFormatError(f"layout file {path} is empty; give a header name,x,y,z,nx,ny,nz and one row per channel")
    header = [h.strip().lower() for h in rows[0]]
    missing = [c for c in _LAYOUT_COLUMNS if c not in header]
    if missing:
        raise FileFormatError(f"layout file {path} lacks column(s) {', '.join(missing)}; "
                              "the header must be name,x,y,z,nx,ny,nz")
    idx = [header.index(c) for c in _LAYOUT_COLUMNS]
    names, num = [], []
    for i, r in enumerate(rows[1:], start=2):
        try:
            names.append(r[idx[0]].strip())
            num.append([float(r[j]) for j in idx[1:]])
        except (IndexError, ValueError):
            raise FileFormatError(f"layout file {path} line {i} is not name + six numbers: {','.join(r)}") from None
    if not names:
        raise FileFormatError(f"layout file {path} has a header but no channels")
    num = np.array(num)
    return Layout(tuple(names), num[:, :3], num[:, 3:])


def write_layout(layout: Layout, path: str | Path) -> Path:
    """Write a layout table readable by :func:`read_layout`."""
    path = check_output(path, what="layout file")
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(_LAYOUT_COLUMNS)
    for name, p, n in zip(layout.names, layout.positions, layout.directions):
        w.writerow([name, *(f"{v:.17g}" for v in p), *(f"{v:.17g}" for v in n)])
    write_text(path, buf.getvalue(), what="layout file")
    return path


@dataclass(frozen=True)
class KinematicSolution(ResultMixin):
    """The 12 kinematic unknowns for every sample.

    Attributes
    ----------
    x : ndarray, shape (12, T)
        Unknowns in :data:`UNKNOWNS` order: specific force at the origin
        (m/s^2), angular acceleration (rad/s^2), entries of
        ``W = w w^T - |w|^2 I`` ((rad/s)^2).
    sensitivity : ndarray, shape (12, M)
        The solve ``x = sensitivity @ readings`` (pseudo-inverse).
    unit_covariance : ndarray, shape (12, 12)
        Covariance of ``x`` per unit variance of white channel noise
        (multiply by the noise variance in (m/s^2)^2).
    condition_number : float
        Condition number of the column-equilibrated design matrix
        (scale-free: independent of the units of length).
    residual_rms : ndarray, shape (T,) or None
        RMS of the readings' residual per sample (m/s^2) when the layout has
        more channels than unknowns, else None.
    """

    x: np.ndarray = field(repr=False)
    sensitivity: np.ndarray = field(repr=False)
    unit_covariance: np.ndarray
    condition_number: float
    residual_rms: np.ndarray | None = field(default=None, repr=False)

    @property
    def specific_force(self) -> np.ndarray:
        return self.x[0:3]

    @property
    def angular_acceleration(self) -> np.ndarray:
        return self.x[3:6]

    @property
    def W(self) -> np.ndarray:  # noqa: N802 - the paper's symbol
        return self.x[6:12]

    @property
    def squares(self) -> np.ndarray:
        """``wx^2, wy^2, wz^2`` (3, T), (rad/s)^2, from the diagonal of W."""
        return square_map() @ self.x[6:9]

    @property
    def products(self) -> np.ndarray:
        """``wx wy, wx wz, wy wz`` (3, T), (rad/s)^2."""
        return self.x[9:12]


def square_map() -> np.ndarray:
    """Matrix mapping ``(W_xx, W_yy, W_zz)`` to ``(wx^2, wy^2, wz^2)``.

    ``W_xx = -(wy^2 + wz^2)`` etc., hence ``wx^2 = (W_xx - W_yy - W_zz)/2``.
    """
    return 0.5 * np.array([[1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]])


def check_layout(layout: Layout) -> tuple[np.ndarray, float]:
    """Pseudo-inverse of the design matrix and its scale-free condition number.

    Raises
    ------
    DegenerateGeometryError
        Fewer than 12 channels, or a layout that cannot separate the 12
        unknowns (e.g. all sensors in one plane, all directions parallel).
    """
    A = layout.design
    if A.shape[0] < 12:
        raise DegenerateGeometryError(
            f"layout has {A.shape[0]} channels but the rigid-body solve needs at least 12 single-axis "
            "accelerometers (e.g. four three-axis chips not in one plane)")
    col = np.linalg.norm(A, axis=0)
    zero = [UNKNOWNS[j] for j in np.flatnonzero(col <= 1e-12 * max(col.max(), 1e-300))]
    if zero:
        raise DegenerateGeometryError(
            f"layout cannot sense {', '.join(zero)} (coplanar sensors or parallel directions); "
            "place sensors off the plane and with sensitive directions along all three axes")
    As = A / col
    s = np.linalg.svd(As, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if not cond < MAX_CONDITION:
        raise DegenerateGeometryError(
            f"layout is degenerate (condition number {cond:.3g}): its sensors cannot separate the 12 "
            "kinematic unknowns; move sensors out of a common plane or line and vary their directions")
    return np.linalg.pinv(A), cond


def solve_kinematics(readings: np.ndarray, layout: Layout) -> KinematicSolution:
    """Least-squares rigid-body solve for every sample at once.

    Parameters
    ----------
    readings : ndarray, shape (M, T)
        Accelerometer readings in m/s^2, rows in ``layout.names`` order.
    layout : Layout
        Positions (m) and directions of the M channels (M >= 12).

    Returns
    -------
    KinematicSolution
        Specific force (m/s^2), angular acceleration (rad/s^2) and the W
        entries ((rad/s)^2) per sample, with the conditioning.

    Raises
    ------
    DegenerateGeometryError
        When the layout cannot determine the 12 unknowns.

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), eq. (1)-(4); METHODS.md 2a.
    """
    y = np.asarray(readings, dtype=float)
    if y.ndim != 2 or y.shape[0] != layout.n_channels:
        raise InputError(f"readings must have shape ({layout.n_channels}, T), got {y.shape}")
    pinv, cond = check_layout(layout)
    x = pinv @ y
    resid = None
    if layout.n_channels > 12:
        r = y - layout.design @ x
        resid = np.sqrt(np.mean(r * r, axis=0) * layout.n_channels / (layout.n_channels - 12))
    return KinematicSolution(x=x, sensitivity=pinv, unit_covariance=pinv @ pinv.T,
                             condition_number=cond, residual_rms=resid)
