"""The project's vocabulary: frozen, validated records that every stage passes along.

Units: lengths in mm, stresses and moduli in MPa, forces in N, fabric tension per unit width in
N/mm, stretches dimensionless, angles in radians inside records (degrees only in configs).
Direction 1 is the course (along a row of stitches), direction 2 the wale.

Every record round-trips through plain dicts and TOML::

    Response.from_dict(r.to_dict())      # equal arrays and metadata
    Yarn.from_toml(y.to_toml())
"""

from __future__ import annotations

import tomllib
from typing import Any, ClassVar, Literal

import attrs
import numpy as np
import tomli_w

from knitframe import validators as v
from knitframe.errors import FieldError
from knitframe.schema import build, to_dict

__all__ = ["EFFECTS", "Yarn", "Fabric", "LoadPath", "Scene", "Provenance", "Response", "Record"]

#: Physical effects a scene may ask for. Solvers declare the subset they can model, and build
#: their residual only from the terms of the effects a scene asks for.
EFFECTS: dict[str, str] = {
    "large_deformation": "geometrically nonlinear kinematics (finite rotations and stretches)",
    "bending": "yarn bending stiffness",
    "contact": "yarn-yarn contact, including contact with periodic images",
    "self_contact": "contact of a yarn with itself",
    "friction": "regularised Coulomb friction at contacts (needs contact)",
    "prestress": "pre-stress step growing the yarn from an undersized radius to dk",
    "anisotropy": "transversely isotropic yarn law / anisotropic fabric response",
}


class Record:
    """Mixin: dict and TOML round trip for attrs records."""

    def to_dict(self) -> dict[str, Any]:
        """Plain-data dict (arrays as lists, None fields omitted)."""
        return to_dict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], path: str = ""):
        """Validated record from a plain dict; errors name ``path.<field>``."""
        return build(cls, data, path)

    def to_toml(self) -> str:
        """TOML text of :meth:`to_dict`."""
        return tomli_w.dumps(self.to_dict())

    @classmethod
    def from_toml(cls, text: str, path: str = ""):
        """Validated record from TOML text."""
        return cls.from_dict(tomllib.loads(text), path)


def _f64(value: Any) -> np.ndarray:
    """Read-only 1-D float64 copy."""
    arr = np.array(value, dtype=np.float64, copy=True).reshape(-1)
    arr.setflags(write=False)
    return arr


def _f64_opt(value: Any) -> np.ndarray | None:
    return None if value is None else _f64(value)


#: Yarn diameters, mm: from a micrometre (finer than any fibre) to 100 mm (a rope).
DIAMETER_RANGE = (1e-3, 100.0)
#: Yarn moduli, MPa: from 1 Pa to 1 TPa (stiffer than any fibre).
MODULUS_RANGE = (1e-6, 1e6)
#: Fibre volume fraction of round fibres packed hexagonally, π/(2√3): the densest a yarn can be.
MAX_PACKING = float(np.pi / (2.0 * np.sqrt(3.0)))
#: Yarn fields that a test can measure (the names ``Yarn.measured`` may list).
MEASURABLE = (
    "d0",
    "dk",
    "E_axial",
    "E_transverse",
    "G_axial",
    "nu",
    "failure_strain",
    "bending_stiffness",
    "tex",
    "fibre_density",
    "compaction_limit",
    "core_modulus",
    "shell_diameter",
    "core_diameter",
    "compression_k",
    "compression_p",
)
#: Yarn fields of the compression law of a soft shell around a core; all four or none.
COMPRESSION_FIELDS = ("shell_diameter", "core_diameter", "compression_k", "compression_p")
_DIAMETER = attrs.validators.and_(v.positive, v.at_least(DIAMETER_RANGE[0]), v.at_most(DIAMETER_RANGE[1]))
_MODULUS = attrs.validators.and_(v.positive, v.at_least(MODULUS_RANGE[0]), v.at_most(MODULUS_RANGE[1]))


@attrs.frozen
class Yarn(Record):
    """A yarn: geometry in the free and the knitted state, and its stiffness.

    Cotton and nylon are transversely isotropic (transverse stiffness ≈ 1e-4 of axial); PET
    monofilament is isotropic (``E_transverse == E_axial``).
    """

    #: library key, e.g. "cotton"
    name: str
    #: free (relaxed) diameter, mm
    d0: float = attrs.field(validator=_DIAMETER)
    #: knitted (compressed) diameter, mm
    dk: float = attrs.field(validator=_DIAMETER)
    #: axial Young's modulus, MPa
    E_axial: float = attrs.field(validator=_MODULUS)
    #: transverse Young's modulus, MPa
    E_transverse: float = attrs.field(validator=_MODULUS)
    #: axial shear modulus, MPa
    G_axial: float | None = attrs.field(default=None, validator=v.optional(_MODULUS))
    #: Poisson ratio, -
    nu: float = attrs.field(default=0.3, validator=v.in_range(-1.0, 0.5, lo_open=True, hi_open=True))
    #: axial strain at failure, -
    failure_strain: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: measured EI, N·mm²; unset: solid section E_axial·π·dk⁴/64
    bending_stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: linear density, tex (g/km); with ``fibre_density`` it gives the packing of the knitted yarn
    tex: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: density of the fibre material, g/cm³
    fibre_density: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: smallest cross-section area over the knitted one (fibres packed solid), -; unset: from tex
    #: and fibre_density (see ``compaction``), else 0.5
    compaction_limit: float | None = attrs.field(
        default=None, validator=v.optional(v.in_range(0.0, 1.0, lo_open=True))
    )
    #: modulus of the packed fibres across the yarn, MPa; unset: E_axial
    core_modulus: float | None = attrs.field(default=None, validator=v.optional(_MODULUS))
    #: compression law (rod contact law ``rod_shell``): outer diameter of the yarn's soft shell, mm
    shell_diameter: float | None = attrs.field(default=None, validator=v.optional(_DIAMETER))
    #: compression law: diameter of the core the shell is squeezed onto, mm
    core_diameter: float | None = attrs.field(default=None, validator=v.optional(_DIAMETER))
    #: compression law: rigidity k of the shell's energy density, N/mm³
    compression_k: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: compression law: exponent p (> 1) of the shell's energy density, -
    compression_p: float | None = attrs.field(
        default=None, validator=v.optional(v.in_range(1.0, 20.0, lo_open=True))
    )
    #: names of the fields that are measured on this yarn; the others are estimates
    measured: frozenset[str] = attrs.field(default=frozenset(), converter=frozenset)
    #: yarn-model plugin name
    model: str = "transverse_isotropic"
    #: where the numbers come from
    source: str = ""

    def __attrs_post_init__(self) -> None:
        if self.dk > self.d0 * (1 + 1e-12):
            raise FieldError("dk", f"must be <= d0 = {self.d0}, got {self.dk}")
        unknown = sorted(set(self.measured) - set(MEASURABLE))
        if unknown:
            raise FieldError(
                "measured", f"unknown field {unknown[0]!r}; expected some of {', '.join(MEASURABLE)}"
            )
        if self.tex is not None and self.fibre_density is not None and self.packing > 1.0 + 1e-9:
            raise FieldError(
                "tex",
                f"{self.tex:g} tex of fibre of {self.fibre_density:g} g/cm³ does not fit in a yarn of "
                f"dk = {self.dk:g} mm (packing {self.packing:.3g} > 1)",
            )
        given = [f for f in COMPRESSION_FIELDS if getattr(self, f) is not None]
        if given and len(given) < len(COMPRESSION_FIELDS):
            missing = next(f for f in COMPRESSION_FIELDS if getattr(self, f) is None)
            raise FieldError(
                missing,
                f"the compression law needs all of {', '.join(COMPRESSION_FIELDS)}; {', '.join(given)} given",
            )
        if given and self.core_diameter >= self.shell_diameter:
            raise FieldError(
                "core_diameter",
                f"must be < shell_diameter = {self.shell_diameter:g} mm, got {self.core_diameter:g}",
            )
        solid = self.E_axial * np.pi * self.d0**4 / 64.0
        if self.bending_stiffness is not None and self.bending_stiffness > solid:
            raise FieldError(
                "bending_stiffness",
                f"must be <= {solid:.4g} N·mm², the solid rod of diameter d0 and "
                f"modulus E_axial (no yarn is stiffer), got {self.bending_stiffness:g}",
            )

    @property
    def rk(self) -> float:
        """Knitted radius dk/2, mm."""
        return 0.5 * self.dk

    @property
    def isotropic(self) -> bool:
        """True when the transverse modulus equals the axial one."""
        return bool(np.isclose(self.E_axial, self.E_transverse))

    @property
    def G_A(self) -> float:
        """Axial shear modulus, MPa: ``G_axial``, else E_transverse / (2(1 + ν)).

        Unset, the fibres slide past each other along the yarn as easily as across it; an
        isotropic yarn gets E/(2(1 + ν)) the same way.
        """
        return self.G_axial if self.G_axial is not None else self.E_transverse / (2.0 * (1.0 + self.nu))

    @property
    def EI(self) -> float:
        """Bending stiffness, N·mm²: ``bending_stiffness``, else the solid section E_axial·π·dk⁴/64."""
        if self.bending_stiffness is not None:
            return self.bending_stiffness
        return self.E_axial * np.pi * self.dk**4 / 64.0

    @property
    def packing(self) -> float | None:
        """Fibre volume fraction of the knitted yarn φk = (tex/ρ) / (π dk²/4), or None.

        tex/ρ is the fibres' cross-section: 1 tex = 1e-6 g/mm over ρ·1e-3 g/mm³ gives 1e-3 tex/ρ mm².
        """
        if self.tex is None or self.fibre_density is None:
            return None
        return 1e-3 * self.tex / self.fibre_density / (np.pi * self.dk**2 / 4.0)

    @property
    def compaction(self) -> float:
        """Smallest cross-section area over the knitted one, J_min, -.

        ``compaction_limit`` if given; else φk / φmax with φmax = :data:`MAX_PACKING` (round
        fibres packed hexagonally) when tex and fibre density are known; else 0.5. Capped at 1
        (a monofilament cannot be compacted).
        """
        if self.compaction_limit is not None:
            return self.compaction_limit
        phi = self.packing
        if phi is None:
            return 0.5
        return float(min(phi / MAX_PACKING, 1.0))

    @property
    def has_compression_law(self) -> bool:
        """True when the record carries the shell's compression law (:data:`COMPRESSION_FIELDS`)."""
        return self.compression_k is not None

    @property
    def core_E(self) -> float:
        """Modulus of the packed fibres across the yarn, MPa: ``core_modulus``, else E_axial."""
        return self.core_modulus if self.core_modulus is not None else self.E_axial


@attrs.frozen
class Fabric(Record):
    """A knitted fabric: pattern, stitch length and yarn.

    Give the stitch length as a machine setting (``stitch_length``, e.g. 10, 11, 12) and/or as
    the arc length of yarn per stitch (``arc_length`` in mm); pattern plugins map one to the other.
    """

    #: pattern plugin name, e.g. "jersey"
    pattern: str
    #: yarn record, or in a config a yarn-library name
    yarn: Yarn
    #: machine setting, -
    stitch_length: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: yarn per stitch, mm
    arc_length: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: stitch width, mm
    course_pitch: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: stitch height, mm
    wale_pitch: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: options of the pattern plugin, e.g. stitch_lengths
    pattern_options: dict[str, Any] = attrs.Factory(dict)

    def __attrs_post_init__(self) -> None:
        if self.stitch_length is None and self.arc_length is None:
            raise FieldError("stitch_length", "give stitch_length (machine setting) or arc_length (mm)")


#: Stretches a load path may prescribe: a fabric squeezed to a tenth of its size has no room for its
#: yarns, and 6 is the largest stretch of ``max_strain`` (5).
STRETCH_RANGE = (0.1, 6.0)
#: Most points of a load path (as ``steps``).
MAX_LOAD_POINTS = 100000


@attrs.frozen
class LoadPath(Record):
    """Macroscopic load path of the unit cell.

    ``equibiaxial``: λ1 = λ2 = 1 + ε. ``uniaxial``: λ along ``direction`` = 1 + ε, the other
    side free (its tension is zero). ``general``: λ1(t), λ2(t) given point by point.
    """

    #: load-path type
    kind: Literal["equibiaxial", "uniaxial", "general"] = "equibiaxial"
    #: engineering strain, -
    max_strain: float = attrs.field(default=0.3, validator=v.strain_limit)
    #: load increments, -
    steps: int = attrs.field(default=10, validator=v.in_range(1, MAX_LOAD_POINTS))
    #: loaded direction for ``uniaxial``
    direction: Literal["course", "wale"] = "course"
    #: course stretch path for ``general``, -
    lambda1: tuple[float, ...] = ()
    #: wale stretch path for ``general``, -
    lambda2: tuple[float, ...] = ()

    def __attrs_post_init__(self) -> None:
        if self.kind == "general":
            if not self.lambda1 or len(self.lambda1) != len(self.lambda2):
                raise FieldError(
                    "lambda1", "general load path needs lambda1 and lambda2 of equal, non-zero length"
                )
            if len(self.lambda1) > MAX_LOAD_POINTS:
                raise FieldError(
                    "lambda1", f"must hold at most {MAX_LOAD_POINTS} points, got {len(self.lambda1)}"
                )
            lo, hi = STRETCH_RANGE
            for name in ("lambda1", "lambda2"):
                for i, lam in enumerate(getattr(self, name)):
                    if not lo <= lam <= hi:
                        raise FieldError(f"{name}[{i}]", f"stretch must be in [{lo:g}, {hi:g}], got {lam:g}")

    @property
    def response_kind(self) -> str:
        """The ``Response.load`` this path produces: ``equibiaxial``, ``uniaxial-course``, ``uniaxial-wale``
        or ``general``."""
        return f"uniaxial-{self.direction}" if self.kind == "uniaxial" else self.kind

    def stretches(self) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Prescribed stretches per step, excluding the undeformed state.

        Returns ``(t, lam1, lam2)`` with pseudo-time ``t`` in (0, 1]; a free direction is None.
        """
        if self.kind == "general":
            n = len(self.lambda1)
            return np.arange(1, n + 1) / n, np.asarray(self.lambda1), np.asarray(self.lambda2)
        t = np.arange(1, self.steps + 1) / self.steps
        lam = 1.0 + self.max_strain * t
        if self.kind == "equibiaxial":
            return t, lam, lam.copy()
        return (t, lam, None) if self.direction == "course" else (t, None, lam)


@attrs.frozen
class Scene(Record):
    """What to simulate: a load path, the effects to include, and the outputs wanted."""

    #: macroscopic load path
    load: LoadPath = attrs.Factory(LoadPath)
    #: names from :data:`EFFECTS`
    effects: frozenset[str] = attrs.field(
        default=frozenset({"large_deformation", "bending", "contact"}),
        converter=frozenset,
        validator=v.subset_of(EFFECTS),
    )
    #: what to write besides the Response
    outputs: frozenset[str] = attrs.field(
        default=frozenset({"response"}),
        converter=frozenset,
        validator=v.subset_of(("response", "vtu", "checkpoints")),
    )

    def __attrs_post_init__(self) -> None:
        if "friction" in self.effects and "contact" not in self.effects:
            raise FieldError("effects", "'friction' needs 'contact'")


@attrs.frozen
class Provenance(Record):
    """Where a Response came from."""

    #: what produced the curve
    kind: Literal["experiment", "simulation", "model"] = "experiment"
    #: file name, solver name or model description
    source: str = ""
    #: solver plugin name, for simulations
    solver: str | None = None
    #: mesh summary, for simulations
    mesh: str | None = None
    #: seconds
    wall_time: float | None = None
    #: false if a solver stopped early
    converged: bool = True
    #: free text
    notes: str = ""
    #: plugin versions, options …
    extra: dict[str, Any] = attrs.Factory(dict)


LoadKind = Literal["equibiaxial", "uniaxial-course", "uniaxial-wale", "general"]


@attrs.frozen(eq=False)
class Response(Record):
    """A fabric's tension-stretch response, measured or simulated.

    ``T1``, ``T2`` are tensions per unit width (N/mm) along the course and the wale; ``lambda1``,
    ``lambda2`` are the stretches. For ``uniaxial-course`` the wale side is free (T2 = 0) and
    ``lambda2`` is the measured lateral stretch; ``uniaxial-wale`` likewise. The ``*_sd`` arrays
    are one standard deviation over ``n_samples`` repeats. All arrays have shape (n,).
    """

    #: course stretch, -
    lambda1: np.ndarray = attrs.field(converter=_f64, validator=v.finite_array)
    #: wale stretch, -
    lambda2: np.ndarray = attrs.field(converter=_f64, validator=v.finite_array)
    #: course tension, N/mm
    T1: np.ndarray = attrs.field(converter=_f64, validator=v.finite_array)
    #: wale tension, N/mm
    T2: np.ndarray = attrs.field(converter=_f64, validator=v.finite_array)
    #: which sides are loaded and which are free
    load: LoadKind = "equibiaxial"
    #: curve name
    label: str = ""
    #: repeats behind the mean
    n_samples: int = attrs.field(default=1, validator=v.in_range(1, 10**9))
    #: N/mm
    T1_sd: np.ndarray | None = attrs.field(default=None, converter=_f64_opt, validator=v.finite_array)
    #: N/mm
    T2_sd: np.ndarray | None = attrs.field(default=None, converter=_f64_opt, validator=v.finite_array)
    #: -
    lambda1_sd: np.ndarray | None = attrs.field(default=None, converter=_f64_opt, validator=v.finite_array)
    #: -
    lambda2_sd: np.ndarray | None = attrs.field(default=None, converter=_f64_opt, validator=v.finite_array)
    #: origin of the curve
    provenance: Provenance = attrs.Factory(Provenance)

    _ARRAYS: ClassVar[tuple[str, ...]] = (
        "lambda1",
        "lambda2",
        "T1",
        "T2",
        "T1_sd",
        "T2_sd",
        "lambda1_sd",
        "lambda2_sd",
    )

    def __attrs_post_init__(self) -> None:
        n = self.lambda1.shape[0]
        if n == 0:
            raise FieldError("lambda1", "must hold at least one point")
        for name in self._ARRAYS:
            arr = getattr(self, name)
            if arr is not None and arr.shape[0] != n:
                raise FieldError(name, f"must have the same length as lambda1 ({n}), got {arr.shape[0]}")
        for name in ("lambda1", "lambda2"):
            arr = getattr(self, name)
            if np.any(arr <= 0):
                i = int(np.flatnonzero(arr <= 0)[0])
                raise FieldError(name, f"stretch must be > 0, got {arr[i]} at index {i}")

    def __len__(self) -> int:
        return int(self.lambda1.shape[0])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Response):
            return NotImplemented
        for name in self._ARRAYS:
            a, b = getattr(self, name), getattr(other, name)
            if (a is None) != (b is None) or (a is not None and not np.array_equal(a, b)):
                return False
        return (self.load, self.label, self.n_samples, self.provenance) == (
            other.load,
            other.label,
            other.n_samples,
            other.provenance,
        )

    __hash__ = None  # type: ignore[assignment]

    @property
    def loaded_direction(self) -> int | None:
        """0 for a uniaxial-course test, 1 for uniaxial-wale, None otherwise."""
        return {"uniaxial-course": 0, "uniaxial-wale": 1}.get(self.load)

    def evolve(self, **changes: Any) -> Response:
        """Copy with some fields replaced."""
        return attrs.evolve(self, **changes)
