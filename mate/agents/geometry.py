"""Angle arithmetic in degrees and `Vector2D`, the small plane-vector type the agents reason with.

Conventions (as the environment's, docs/environment/entities.md): all angles are in degrees;
`normalize_angle` maps onto [-180, 180); `arctan2_deg` returns values in (-180, 180].
Every function works element-wise on floats and on numpy arrays alike.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    'RAD2DEG', 'DEG2RAD', 'normalize_angle', 'sin_deg', 'cos_deg', 'tan_deg', 'arcsin_deg', 'arccos_deg',
    'arctan2_deg', 'cartesian2polar', 'polar2cartesian', 'Vector2D',
]

RAD2DEG = 180.0 / math.pi
DEG2RAD = math.pi / 180.0


def normalize_angle(angle):
    """`angle` (degrees) wrapped onto [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


def sin_deg(angle):
    """Sine of an angle in degrees."""
    return np.sin(np.multiply(angle, DEG2RAD))


def cos_deg(angle):
    """Cosine of an angle in degrees."""
    return np.cos(np.multiply(angle, DEG2RAD))


def tan_deg(angle):
    """Tangent of an angle in degrees."""
    return np.tan(np.multiply(angle, DEG2RAD))


def arcsin_deg(x):
    """Arc sine in degrees, in [-90, 90]."""
    return np.multiply(np.arcsin(x), RAD2DEG)


def arccos_deg(x):
    """Arc cosine in degrees, in [0, 180]."""
    return np.multiply(np.arccos(x), RAD2DEG)


def arctan2_deg(y, x):
    """Bearing of the vector (x, y) in degrees, in (-180, 180]."""
    return np.multiply(np.arctan2(y, x), RAD2DEG)


def cartesian2polar(x, y) -> np.ndarray:
    """`array([rho, phi])` of the point (x, y); phi in degrees. Shape (2, ...) for array inputs."""
    return np.array([np.hypot(x, y), arctan2_deg(y, x)])


def polar2cartesian(rho, phi) -> np.ndarray:
    """`array([x, y])` of the point at distance rho and bearing phi (degrees). Shape (2, ...)."""
    return np.multiply(rho, np.array([cos_deg(phi), sin_deg(phi)]))


class Vector2D:
    """A plane vector known by its components or by (norm, angle in degrees), converted lazily.

    Build it from `vector=(x, y)` or from both `norm` and `angle`; `origin` (default (0, 0)) is
    where the vector starts, so `endpoint = origin + vector`. The angle is kept in [-180, 180).
    A negative norm is stored as its absolute value with the angle turned by 180 degrees.
    `a + b` and `a - b` keep `a.origin`; `k * v` scales the norm. As in the original MATE,
    `a == b` compares the angles only.
    """

    __slots__ = ('_vector', '_norm', '_angle', 'origin')

    def __init__(self, vector=None, norm=None, angle=None, origin=None) -> None:
        self.origin = np.zeros(2) if origin is None else np.asarray(origin, dtype=np.float64).copy()
        self._vector = self._norm = self._angle = None
        if vector is not None and norm is None and angle is None:
            self.vector = vector
        elif vector is None and norm is not None and angle is not None:
            self._set_polar(float(norm), float(angle))
        else:
            raise ValueError('Vector2D needs either `vector` or both `norm` and `angle`')

    def _set_polar(self, norm: float, angle: float) -> None:
        if norm < 0.0:
            norm, angle = -norm, angle + 180.0
        self._norm, self._angle, self._vector = norm, normalize_angle(angle), None

    @property
    def vector(self) -> np.ndarray:
        """The components (x, y), float64 (2,)."""
        if self._vector is None:
            theta = self._angle * DEG2RAD
            self._vector = np.array([self._norm * math.cos(theta), self._norm * math.sin(theta)])
        return self._vector

    @vector.setter
    def vector(self, value) -> None:
        value = np.array(value, dtype=np.float64).reshape(2)
        self._vector, self._norm, self._angle = value, None, None

    @property
    def norm(self) -> float:
        """Length of the vector."""
        if self._norm is None:
            self._norm = math.hypot(self._vector[0], self._vector[1])
        return self._norm

    @norm.setter
    def norm(self, value: float) -> None:
        self._set_polar(float(value), self.angle)

    @property
    def angle(self) -> float:
        """Bearing of the vector in degrees: (-180, 180] when computed from components, [-180, 180) when set."""
        if self._angle is None:
            self._angle = math.atan2(self._vector[1], self._vector[0]) * RAD2DEG
        return self._angle

    @angle.setter
    def angle(self, value: float) -> None:
        self._set_polar(self.norm, float(value))

    @property
    def x(self) -> float:
        return float(self.vector[0])

    @property
    def y(self) -> float:
        return float(self.vector[1])

    @property
    def endpoint(self) -> np.ndarray:
        """`origin + vector`, float64 (2,)."""
        return self.origin + self.vector

    @endpoint.setter
    def endpoint(self, value) -> None:
        self.vector = np.asarray(value, dtype=np.float64) - self.origin

    def copy(self) -> Vector2D:
        return Vector2D(vector=self.vector.copy(), origin=self.origin)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        array = self.vector
        return array.astype(dtype) if dtype is not None else array.copy()

    def __add__(self, other: Vector2D) -> Vector2D:
        return Vector2D(vector=self.vector + np.asarray(other, dtype=np.float64), origin=self.origin)

    def __sub__(self, other: Vector2D) -> Vector2D:
        return Vector2D(vector=self.vector - np.asarray(other, dtype=np.float64), origin=self.origin)

    def __mul__(self, factor: float) -> Vector2D:
        return Vector2D(norm=self.norm * factor, angle=self.angle, origin=self.origin)

    __rmul__ = __mul__

    def __imul__(self, factor: float) -> Vector2D:
        self._set_polar(self.norm * factor, self.angle)
        return self

    def __neg__(self) -> Vector2D:
        return Vector2D(vector=-self.vector, origin=self.origin)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Vector2D):
            return NotImplemented
        return self.angle == other.angle

    __hash__ = None

    def __repr__(self) -> str:
        x, y = self.vector
        return f'Vector2D(x={x:.6g}, y={y:.6g}, norm={self.norm:.6g}, angle={self.angle:.6g})'
