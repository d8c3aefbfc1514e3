"""
The rig description: ``config/rig.yaml`` loaded into validated dataclasses.

Every number of the thesis rig (Cade 2006, Tables 2.1-2.3 and section 2.1) lives in that file;
code reads it through :func:`load_rig`. Axial positions ``z`` are measured from the drive end;
sensor planes, bearings and disks are listed in thesis order (from the non-driven end).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from amb_common.errors import RigError

DEFAULT_RIG_PATH = Path(__file__).resolve().parent.parent / "config" / "rig.yaml"


@dataclass(frozen=True)
class Material:
    """Isotropic material: density ``rho`` (kg/m^3), Young's modulus ``E`` (Pa), ``poisson``."""

    rho: float
    E: float
    poisson: float

    @property
    def G(self) -> float:  # noqa: N802 - shear modulus symbol
        """Shear modulus, Pa."""
        return self.E / (2.0 * (1.0 + self.poisson))


@dataclass(frozen=True)
class RigidDisk:
    """
    A rigid, axially symmetric disk on the shaft (eq. 2.12-2.13).

    Attributes
    ----------
    tag : str
        Name (``D1``..., ``CORE1``..., ``C1``...).
    z : float
        Axial position of its centre, m from the drive end.
    rho : float
        Density of the geometric body, kg/m^3.
    width, inner_radius, outer_radius : float
        Geometry, m.
    mass : float
        Mass used by the model, kg. Inertias are the geometric ones scaled by
        ``mass / geometric_mass`` (a lighter body of the same shape).
    """

    tag: str
    z: float
    rho: float
    width: float
    inner_radius: float
    outer_radius: float
    mass: float

    @property
    def geometric_mass(self) -> float:
        """Mass of the annulus from its geometry and density, kg."""
        return self.rho * math.pi * (self.outer_radius**2 - self.inner_radius**2) * self.width

    @property
    def polar_inertia(self) -> float:
        """Polar moment of inertia I_p about the spin axis, kg m^2."""
        return 0.5 * self.mass * (self.outer_radius**2 + self.inner_radius**2)

    @property
    def diametral_inertia(self) -> float:
        """Diametral moment of inertia I_d about a diameter through the centre, kg m^2."""
        r2 = self.outer_radius**2 + self.inner_radius**2
        return self.mass * (3.0 * r2 + self.width**2) / 12.0


@dataclass(frozen=True)
class SensorPlane:
    """A pair of orthogonal probes (x, y) at axial position ``z`` (m); role inner/outer."""

    tag: str
    z: float
    role: str


@dataclass(frozen=True)
class Bearing:
    """An AMB at axial position ``z`` (m) fed back from sensor plane ``sensor_plane`` (1-based)."""

    tag: str
    z: float
    sensor_plane: int


@dataclass(frozen=True)
class ClearanceBearing:
    """Auxiliary or retainer bearing at ``z`` (m) with radial clearance (m)."""

    tag: str
    z: float
    kind: str
    radial_clearance: float


@dataclass(frozen=True)
class ShaftData:
    """
    Uniform shaft: length, radii (m), material, element count and element options.

    ``nonstructural_mass`` (kg) is mass the shaft carries without stiffness (sleeves, fits,
    the coupling's hub: whatever makes the thesis's "50 kg" shaft heavier than its Table 2.1
    section), spread uniformly along the length: it adds to the inertia terms of the shaft
    elements (translational, rotary and gyroscopic, as a higher density would) and not to
    their stiffness.
    """

    length: float
    outer_radius: float
    inner_radius: float
    material: Material
    elements: int
    shear: bool = True
    rotary_inertia: bool = True
    internal_damping_viscous: float = 0.0
    internal_damping_hysteretic: float = 0.0
    nonstructural_mass: float = 0.0

    @property
    def geometric_mass(self) -> float:
        """Mass of the shaft's section over its length at the material's density, kg."""
        area = math.pi * (self.outer_radius**2 - self.inner_radius**2)
        return self.material.rho * area * self.length

    @property
    def inertia_density(self) -> float:
        """
        Density that carries the shaft's inertia, kg/m^3.

        The material's density raised by the non-structural mass:
        ``rho (1 + m_ns / m_geometric)``.
        """
        return self.material.rho * (1.0 + self.nonstructural_mass / self.geometric_mass)


@dataclass(frozen=True)
class AmbData:
    """AMB data of section 2.3 and Table 2.2 (SI)."""

    Kz: float
    Ki: float
    law: str
    force_limit: float
    pole_area: float
    turns: int
    nominal_air_gap: float
    coil_resistance: float
    coil_inductance: float
    peak_current: float
    peak_voltage: float
    amplifier: str
    amplifier_bandwidth: float

    @property
    def force_slew_rate(self) -> float:
        """
        Fastest change of a control axis's force the amplifiers can make, N/s.

        From the coil equation ``v = R i + L di/dt`` (eq. 2.42): at the peak current the
        amplifier's peak voltage leaves ``V - R I`` across the inductance, so ``|di/dt| >=
        (V - R I) / L`` is always available and the force ``K_i i`` changes at up to ``K_i (V
        - R I) / L``. Table 2.2 (95.2 V, 0.365 ohm, 10 A, 0.0732 H, 572 N/A): 7.15e5 N/s, i.e.
        1150 N per sample at 9.7 Hz x 64 samples per revolution and 334 N at 67 Hz x 32.
        """
        headroom = self.peak_voltage - self.coil_resistance * self.peak_current
        return self.Ki * headroom / self.coil_inductance

    @property
    def bias_current(self) -> float:
        """
        Bias current I_b, A, of the opposing-pair law whose slopes are ``Ki`` and ``Kz``.

        Eq. (2.39)-(2.40) with the levitation current I_s = 0 (gravity is not part of the
        lateral model about the static equilibrium): K_i = 4 k I_b / c_g^2 and
        K_z = 4 k I_b^2 / c_g^3, so I_b = c_g K_z / K_i: 4.70 A with rig.yaml's 2240 N/mm,
        572 N/A and the nominal 1.2 mm gap (4.35 A with the measured mean, 2075 N/mm).
        """
        return self.nominal_air_gap * self.Kz / self.Ki

    @property
    def pair_constant(self) -> float:
        """
        Force constant k of the opposing-pair law (eq. 2.33), N m^2 / A^2.

        ``k = K_i^2 c_g / (4 K_z)``: the constant whose slopes at the origin are the rig's
        ``Ki`` and ``Kz`` over the nominal gap (:attr:`bias_current`). Table 2.2's geometry
        gives ``mu0 N^2 A`` = 4.39e-5 and, with 572 N/A, 2240 N/mm (rig.yaml's Kz: the two
        agree); the measured negative stiffness (2075 N/mm mean) would need 4.73e-5: the
        nominal gap and geometry do not hold the iron and leakage that the measurement sees,
        so the pair law follows the slopes and the gap sets only the scale of its
        nonlinearity.
        """
        return self.Ki**2 * self.nominal_air_gap / (4.0 * self.Kz)


@dataclass(frozen=True)
class PidGains:
    """Decentralised PID of Table 2.3 as force per displacement (N/m, N/(m s), N s/m, rad/s)."""

    Kp: float
    KI: float
    Kd: float
    derivative_cutoff: float


@dataclass(frozen=True)
class ContactData:
    """
    Contact model parameters for eq. (5.5).

    ``race_inertia`` (kg m^2) and ``race_drag`` (N m s) are the inner race of a rolling
    auxiliary bearing (``kind: auxiliary``), which the contact's friction spins up; with
    ``race_inertia = 0`` every race is held at rest (retainers always are).
    """

    model: str
    hertz_stiffness: float
    penalty_stiffness: float
    damping: float
    friction: float
    slip_velocity_scale: float
    rotor_radius: float
    substeps: int
    race_inertia: float = 0.0
    race_drag: float = 0.0


@dataclass(frozen=True)
class SimulationData:
    """Time integration settings: minimum internal rate (Hz), speed quantum (Hz), cache size."""

    internal_rate_min: float = 5000.0
    speed_quantum: float = 0.01
    cache_size: int = 32


@dataclass(frozen=True)
class Rig:
    """The whole rig, as loaded from ``config/rig.yaml``."""

    shaft: ShaftData
    disks: tuple[RigidDisk, ...]
    amb_cores: tuple[RigidDisk, ...]
    collars: tuple[RigidDisk, ...]
    sensor_planes: tuple[SensorPlane, ...]
    bearings: tuple[Bearing, ...]
    clearance_bearings: tuple[ClearanceBearing, ...]
    amb: AmbData
    pid: PidGains
    contact: ContactData
    simulation: SimulationData
    calibration: dict[str, Any] = field(default_factory=dict)
    source: str = ""

    @property
    def feedback_channels(self) -> list[int]:
        """
        Sensor channels (0-based, ``[x1, y1, ..., x4, y4]`` order) the local PID closes on.

        ``[x, y]`` of bearing 1's sensor plane, then of bearing 2's: the inner sensors.
        """
        return [2 * (b.sensor_plane - 1) + a for b in self.bearings[:2] for a in (0, 1)]

    @property
    def plane_clearance_bearings(self) -> tuple[int, ...]:
        """
        Per sensor plane, the clearance bearing axially nearest it (0 if the rig has none).

        1-based indices into ``clearance_bearings`` (on the Bath rig AB1, AB2, R1, R2), in the
        order of ``sensor_planes``: the bearing a contact seen most at that plane is taken to
        be at (the fault monitor's contact events), and whose clearance its probe reads
        against (:attr:`probe_clearance`, the trip levels).
        """
        clear = self.clearance_bearings
        if not clear:
            return tuple(0 for _ in self.sensor_planes)
        return tuple(
            1 + min(range(len(clear)), key=lambda i: abs(clear[i].z - plane.z))
            for plane in self.sensor_planes
        )

    @property
    def probe_clearance(self) -> tuple[float, ...]:
        """
        Per probe channel, the clearance (m) of the auxiliary bearing next to it (inf if none).

        Channels in ``[x1, y1, ..., x4, y4]`` order. A channel whose sensor plane's axially
        nearest clearance bearing is an auxiliary bearing takes its radial clearance: what the
        probe reads, give or take the shaft's slope over the distance between them, when the
        journal touches that bearing (on the Bath rig the inner probes, 40 mm from the
        auxiliary bearings inside the magnets, 0.75 mm). Probes nearest a retainer (the outer
        ones, at the shaft's ends) or with no clearance bearing take inf.
        """
        return self._probe_clearances(kinds=("auxiliary",))

    @property
    def probe_nearest_clearance(self) -> tuple[float, ...]:
        """
        Per probe channel, the clearance (m) of the clearance bearing axially nearest it.

        Channels in ``[x1, y1, ..., x4, y4]`` order; auxiliary bearings and retainers alike
        (on the Bath rig 0.9 mm at the outer probes, by the retainers, and 0.75 mm at the inner
        ones); inf where the rig has none. The room a probe's reading has before that bearing
        is touched, give or take the shaft's slope between them: the early action's check of
        its plans (:func:`amb_apps.plant_models.early_action_model`). :attr:`probe_clearance`
        is the guard's: it trips on the auxiliary bearings only.
        """
        return self._probe_clearances(kinds=None)

    def _probe_clearances(self, kinds: tuple[str, ...] | None) -> tuple[float, ...]:
        """Per probe channel, the nearest clearance bearing's clearance, m.

        inf where the rig has none or its kind is not one of ``kinds`` (None: any kind).
        """
        out: list[float] = []
        for k in self.plane_clearance_bearings:
            nearest = self.clearance_bearings[k - 1] if k else None
            counted = nearest is not None and (kinds is None or nearest.kind in kinds)
            clearance = nearest.radial_clearance if counted else math.inf
            out += [clearance, clearance]
        return tuple(out)

    @property
    def rigid_bodies(self) -> tuple[RigidDisk, ...]:
        """All rigid bodies on the shaft: disks, AMB cores, collars."""
        return self.disks + self.amb_cores + self.collars

    def stations(self) -> list[float]:
        """Axial positions (m) that must be FE nodes: ends, bodies, sensors, bearings."""
        zs = [0.0, self.shaft.length]
        zs += [b.z for b in self.rigid_bodies]
        zs += [s.z for s in self.sensor_planes]
        zs += [b.z for b in self.bearings]
        zs += [c.z for c in self.clearance_bearings]
        return sorted(set(round(z, 9) for z in zs))

    def with_elements(self, elements: int) -> Rig:
        """Copy with another shaft element count."""
        return replace(self, shaft=replace(self.shaft, elements=int(elements)))


def _req(d: dict[str, Any], key: str, where: str) -> Any:
    if not isinstance(d, dict) or key not in d:
        raise RigError(f"rig file: missing key '{key}' in {where}; add it (see config/rig.yaml)")
    return d[key]


def _pos(value: Any, name: str, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise RigError(f"rig file: {name} must be a number, got {value!r}") from exc
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise RigError(f"rig file: {name} must be finite and {kind}, got {v}")
    return v


def _body(
    d: dict[str, Any], materials: dict[str, Material], where: str, length: float
) -> RigidDisk:
    tag = str(_req(d, "tag", where))
    mat_name = _req(d, "material", where)
    if mat_name not in materials:
        raise RigError(
            f"rig file: {where} {tag}: unknown material {mat_name!r}; "
            f"expected one of {sorted(materials)}"
        )
    rho = materials[mat_name].rho
    z = _pos(_req(d, "z", where), f"{where} {tag}.z", allow_zero=True)
    if z > length:
        raise RigError(f"rig file: {where} {tag}.z = {z} m lies beyond the shaft (0..{length} m)")
    width = _pos(_req(d, "width", where), f"{where} {tag}.width")
    ri = _pos(_req(d, "inner_radius", where), f"{where} {tag}.inner_radius", allow_zero=True)
    ro = _pos(_req(d, "outer_radius", where), f"{where} {tag}.outer_radius")
    if ro <= ri:
        raise RigError(f"rig file: {where} {tag}: outer_radius {ro} must exceed inner_radius {ri}")
    geo = RigidDisk(tag, z, rho, width, ri, ro, 0.0).geometric_mass
    mass = _pos(d.get("mass", geo), f"{where} {tag}.mass")
    return RigidDisk(tag, z, rho, width, ri, ro, mass)


def rig_from_dict(data: dict[str, Any], source: str = "") -> Rig:
    """
    Build and validate a :class:`Rig` from the parsed YAML mapping.

    Parameters
    ----------
    data : dict
        Parsed content of a rig file.
    source : str
        Where it came from (for messages).

    Returns
    -------
    Rig

    Raises
    ------
    RigError
        Missing keys, non-physical values, inconsistent references.
    """
    if not isinstance(data, dict):
        raise RigError(f"rig file {source}: expected a mapping at top level, got {type(data)}")
    mats_raw = _req(data, "materials", "top level")
    materials = {
        name: Material(
            _pos(_req(m, "rho", name), f"{name}.rho"),
            _pos(_req(m, "E", name), f"{name}.E"),
            float(_req(m, "poisson", name)),
        )
        for name, m in mats_raw.items()
    }
    s = _req(data, "shaft", "top level")
    mat = _req(s, "material", "shaft")
    if mat not in materials:
        raise RigError(
            f"rig file: shaft material {mat!r} unknown; expected one of {sorted(materials)}"
        )
    elements = int(_req(s, "elements", "shaft"))
    length = _pos(_req(s, "length", "shaft"), "shaft.length")
    shaft = ShaftData(
        length=length,
        outer_radius=_pos(_req(s, "outer_radius", "shaft"), "shaft.outer_radius"),
        inner_radius=_pos(_req(s, "inner_radius", "shaft"), "shaft.inner_radius", allow_zero=True),
        material=materials[mat],
        elements=elements,
        shear=bool(_req(s, "shear", "shaft")),
        rotary_inertia=bool(_req(s, "rotary_inertia", "shaft")),
        internal_damping_viscous=_pos(
            _req(s, "internal_damping_viscous", "shaft"), "shaft.internal_damping_viscous", True
        ),
        internal_damping_hysteretic=_pos(
            _req(s, "internal_damping_hysteretic", "shaft"),
            "shaft.internal_damping_hysteretic",
            True,
        ),
        nonstructural_mass=_pos(s.get("nonstructural_mass", 0.0), "shaft.nonstructural_mass", True),
    )
    disks = tuple(_body(d, materials, "disks", length) for d in data.get("disks", []))
    cores = tuple(_body(d, materials, "amb_cores", length) for d in data.get("amb_cores", []))
    collars = tuple(_body(d, materials, "collars", length) for d in data.get("collars", []))
    planes = tuple(
        SensorPlane(
            str(_req(p, "tag", "sensor_planes")),
            _pos(_req(p, "z", "sensor_planes"), "sensor_planes.z", True),
            str(p.get("role", "outer")),
        )
        for p in _req(data, "sensor_planes", "top level")
    )
    if len(planes) != 4:
        raise RigError(f"rig file: expected 4 sensor planes (8 channels x1..y4), got {len(planes)}")
    bearings = tuple(
        Bearing(
            str(_req(b, "tag", "bearings")),
            _pos(_req(b, "z", "bearings"), "bearings.z", True),
            int(_req(b, "sensor_plane", "bearings")),
        )
        for b in _req(data, "bearings", "top level")
    )
    if len(bearings) != 2:
        raise RigError(f"rig file: expected 2 bearings (4 control axes), got {len(bearings)}")
    for b in bearings:
        if not 1 <= b.sensor_plane <= 4:
            raise RigError(
                f"rig file: bearing {b.tag}.sensor_plane must be 1..4, got {b.sensor_plane}"
            )
    clearance = tuple(
        ClearanceBearing(
            str(_req(c, "tag", "clearance_bearings")),
            _pos(_req(c, "z", "clearance_bearings"), "clearance_bearings.z", True),
            str(_req(c, "kind", "clearance_bearings")),
            _pos(_req(c, "radial_clearance", "clearance_bearings"), "radial_clearance"),
        )
        for c in data.get("clearance_bearings", [])
    )
    for z in [p.z for p in planes] + [b.z for b in bearings] + [c.z for c in clearance]:
        if z > length:
            raise RigError(f"rig file: position z = {z} m lies beyond the shaft (0..{length} m)")
    a = _req(data, "amb", "top level")
    law = str(_req(a, "law", "amb"))
    if law not in ("linear", "nonlinear"):
        raise RigError(f"rig file: amb.law must be 'linear' or 'nonlinear', got {law!r}")
    amplifier = str(_req(a, "amplifier", "amb"))
    if amplifier not in ("ideal", "coil"):
        raise RigError(f"rig file: amb.amplifier must be 'ideal' or 'coil', got {amplifier!r}")
    amb = AmbData(
        Kz=_pos(_req(a, "Kz", "amb"), "amb.Kz", True),
        Ki=_pos(_req(a, "Ki", "amb"), "amb.Ki"),
        law=law,
        force_limit=_pos(_req(a, "force_limit", "amb"), "amb.force_limit"),
        pole_area=_pos(_req(a, "pole_area", "amb"), "amb.pole_area"),
        turns=int(_req(a, "turns", "amb")),
        nominal_air_gap=_pos(_req(a, "nominal_air_gap", "amb"), "amb.nominal_air_gap"),
        coil_resistance=_pos(_req(a, "coil_resistance", "amb"), "amb.coil_resistance"),
        coil_inductance=_pos(_req(a, "coil_inductance", "amb"), "amb.coil_inductance"),
        peak_current=_pos(_req(a, "peak_current", "amb"), "amb.peak_current"),
        peak_voltage=_pos(_req(a, "peak_voltage", "amb"), "amb.peak_voltage"),
        amplifier=amplifier,
        amplifier_bandwidth=_pos(_req(a, "amplifier_bandwidth", "amb"), "amb.amplifier_bandwidth"),
    )
    if amb.force_slew_rate <= 0.0:
        raise RigError(
            f"rig file: amb.peak_voltage ({amb.peak_voltage} V) must exceed coil_resistance x "
            f"peak_current ({amb.coil_resistance * amb.peak_current:g} V)"
        )
    p = _req(data, "pid", "top level")
    pid = PidGains(
        Kp=_pos(_req(p, "Kp", "pid"), "pid.Kp", True),
        KI=_pos(_req(p, "KI", "pid"), "pid.KI", True),
        Kd=_pos(_req(p, "Kd", "pid"), "pid.Kd", True),
        derivative_cutoff=_pos(_req(p, "derivative_cutoff", "pid"), "pid.derivative_cutoff"),
    )
    c = _req(data, "contact", "top level")
    model = str(_req(c, "model", "contact"))
    if model not in ("hertz", "penalty"):
        raise RigError(f"rig file: contact.model must be 'hertz' or 'penalty', got {model!r}")
    contact = ContactData(
        model=model,
        hertz_stiffness=_pos(_req(c, "hertz_stiffness", "contact"), "contact.hertz_stiffness"),
        penalty_stiffness=_pos(
            _req(c, "penalty_stiffness", "contact"), "contact.penalty_stiffness"
        ),
        damping=_pos(_req(c, "damping", "contact"), "contact.damping", True),
        friction=_pos(_req(c, "friction", "contact"), "contact.friction", True),
        slip_velocity_scale=_pos(
            _req(c, "slip_velocity_scale", "contact"), "contact.slip_velocity_scale"
        ),
        rotor_radius=_pos(_req(c, "rotor_radius", "contact"), "contact.rotor_radius"),
        substeps=max(1, int(_req(c, "substeps", "contact"))),
        race_inertia=_pos(c.get("race_inertia", 0.0), "contact.race_inertia", True),
        race_drag=_pos(c.get("race_drag", 0.0), "contact.race_drag", True),
    )
    sm = _req(data, "simulation", "top level")
    simulation = SimulationData(
        internal_rate_min=_pos(
            _req(sm, "internal_rate_min", "simulation"), "simulation.internal_rate_min"
        ),
        speed_quantum=_pos(_req(sm, "speed_quantum", "simulation"), "simulation.speed_quantum"),
        cache_size=max(1, int(_req(sm, "cache_size", "simulation"))),
    )
    rig = Rig(
        shaft=shaft,
        disks=disks,
        amb_cores=cores,
        collars=collars,
        sensor_planes=planes,
        bearings=bearings,
        clearance_bearings=clearance,
        amb=amb,
        pid=pid,
        contact=contact,
        simulation=simulation,
        calibration=dict(data.get("calibration", {}) or {}),
        source=source,
    )
    n_min = len(rig.stations()) - 1
    if elements < n_min:
        raise RigError(
            f"rig file: shaft.elements = {elements} is fewer than the {n_min} elements needed to "
            "put a node at every disk, core, collar, sensor plane and bearing; raise it"
        )
    return rig


def load_rig(path: str | Path | None = None) -> Rig:
    """
    Load and validate the rig description.

    Parameters
    ----------
    path : str or Path, optional
        YAML file; default ``config/rig.yaml`` of this repository.

    Returns
    -------
    Rig

    Raises
    ------
    RigError
        If the file is missing or invalid (the message names the key and the fix).
    """
    p = Path(path) if path is not None else DEFAULT_RIG_PATH
    if not p.is_file():
        raise RigError(f"rig file not found: {p}; pass the path of config/rig.yaml")
    try:
        with p.open(encoding="utf-8") as fh:
            data = yaml.safe_load(fh)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise RigError(f"rig file {p} is not readable YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise RigError(f"rig file {p}: expected a mapping of rig keys, got {type(data).__name__}")
    return rig_from_dict(data, source=str(p))
