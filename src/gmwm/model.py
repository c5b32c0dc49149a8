"""Composite error models: sums of independent latent processes written as strings.

``Model("WN+RW+AR1+SIN")``, ``Model("2*AR1+2*SIN")``, ``Model("QN+WN+2*GM+RW+DR", freq=250)``.
Components are held in a canonical order (QN, WN, AR1, GM, SIN, RW, DR, then by index), and
parameters have stable flat names ``TYPE[k].name`` such as ``AR1[1].phi`` or ``SIN[2].beta``.
Components of one type are numbered by the time scale they act on, shortest first (AR1 by
increasing phi, GM by increasing correlation time, SIN by decreasing beta): :meth:`Model.canonical`
applies that order to any parameter vector so estimates are comparable across fits.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .errors import ModelError
from .processes import PROCESSES, SINGLETONS, FreeMap, Process

_TERM = re.compile(r"^\s*(?:(\d+)\s*\*\s*)?([A-Za-z][A-Za-z0-9]*)\s*$")


@dataclass(frozen=True)
class Component:
    """One process of a model: its type, index k (1-based within the type) and parameter slice."""

    process: Process
    index: int
    start: int

    @property
    def name(self) -> str:
        return f"{self.process.name}[{self.index}]"

    @property
    def slice(self) -> slice:
        return slice(self.start, self.start + self.process.n_params)

    @property
    def param_names(self) -> list[str]:
        return [f"{self.name}.{p}" for p in self.process.param_names]


def spec_of(counts: Mapping[str, int]) -> str:
    """Model string of process counts in the given order, zero counts skipped:
    ``{'AR1': 2, 'WN': 1}`` -> ``'2*AR1+WN'``."""
    return "+".join(f"{n}*{name}" if n > 1 else name for name, n in counts.items() if n > 0)


def parse_model(spec: str) -> dict[str, int]:
    """Count of each process type in a model string, e.g. ``"2*AR1+WN"`` -> {AR1: 2, WN: 1}."""
    if not isinstance(spec, str) or not spec.strip():
        raise ModelError("empty model string; write e.g. 'WN+RW+AR1'")
    counts: dict[str, int] = {}
    for term in spec.split("+"):
        match = _TERM.match(term)
        if match is None:
            raise ModelError(f"cannot read model term {term.strip()!r} in {spec!r}; "
                             "write terms like 'WN' or '2*AR1' joined by '+'")
        mult = int(match.group(1) or 1)
        name = match.group(2).upper()
        if name not in PROCESSES:
            raise ModelError(f"unknown process {match.group(2)!r} in {spec!r}; "
                             f"known: {', '.join(PROCESSES)}")
        if mult < 1:
            raise ModelError(f"multiplicity must be at least 1 in {term.strip()!r}")
        counts[name] = counts.get(name, 0) + mult
    for name in SINGLETONS:
        if counts.get(name, 0) > 1:
            raise ModelError(f"{name} appears {counts[name]} times in {spec!r}; a sum of "
                             f"{name} processes is one {name} process (not identifiable)")
    return counts



@dataclass
class SimulationPlan:
    """A model's components in the block simulators' primitive form
    (:meth:`Model.simulation_plan`): the walk-plus-noise stream (``walk``, coefficients ``a_w``,
    ``b_w``), the drift per sample ``omega``, and the AR1 ``[phi, innovation sd, state]``, QN
    ``[q, previous uniform]`` and SIN ``(alpha, beta, phase)`` entries (states are updated in
    place by the simulators)."""

    walk: bool
    a_w: float
    b_w: float
    omega: float
    ar1: list[list[float]]
    qn: list[list[float]]
    sines: list[tuple[float, float, float]]

class Model:
    """A sum of independent processes with flat, named parameters.

    Parameters
    ----------
    spec : model string, e.g. ``"WN+RW+AR1+SIN"``; ``k*TYPE`` repeats a process.
    freq : sampling frequency in Hz (only GM parameters and scales in seconds depend on it).
    """

    def __init__(self, spec: str | Model, freq: float = 1.0):
        if isinstance(spec, Model):
            freq = spec.freq if freq == 1.0 else freq
            spec = spec.spec
        if not np.isfinite(freq) or freq <= 0:
            raise ModelError(f"sampling frequency must be positive, got {freq}")
        counts = parse_model(spec)
        self.freq = float(freq)
        self.components: list[Component] = []
        start = 0
        for name, proc in PROCESSES.items():
            for k in range(1, counts.get(name, 0) + 1):
                self.components.append(Component(proc, k, start))
                start += proc.n_params
        self.n_params = start
        self.spec = spec_of({name: counts.get(name, 0) for name in PROCESSES})
        self.param_names = [n for c in self.components for n in c.param_names]
        self._free = FreeMap(tuple(k for c in self.components for k in c.process.free_map_kinds))
        self._parts = [(c.process, c.slice) for c in self.components]

    def __repr__(self) -> str:
        return f"Model({self.spec!r}, freq={self.freq:g})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Model) and (self.spec, self.freq) == (other.spec, other.freq)

    def __hash__(self) -> int:
        return hash((self.spec, self.freq))

    @property
    def component_names(self) -> list[str]:
        return [c.name for c in self.components]

    @property
    def is_linear(self) -> bool:
        """True if the WV is linear in a transform of the parameters (only QN, WN, RW, DR)."""
        return all(c.process.linear for c in self.components)

    def count(self, name: str) -> int:
        return sum(c.process.name == name for c in self.components)

    # -- parameter vectors ----------------------------------------------------------------------
    def theta(self, values: Mapping[str, float] | None = None, *, estimate: bool = False,
              **kwargs: float) -> np.ndarray:
        """Parameter vector from a mapping of flat names, validated and in canonical order.
        ``estimate=True`` also accepts a component whose scale parameter is exactly 0 (a fit at
        the boundary; see :meth:`check`)."""
        given = dict(values or {}, **kwargs)
        unknown = sorted(set(given) - set(self.param_names))
        if unknown:
            raise ModelError(f"unknown parameter(s) {', '.join(unknown)} for model {self.spec}; "
                             f"expected {', '.join(self.param_names)}")
        missing = [n for n in self.param_names if n not in given]
        if missing:
            raise ModelError(f"missing value for parameter(s) {', '.join(missing)}")
        theta = np.array([float(given[n]) for n in self.param_names])
        self.check(theta, boundary_ok=estimate)
        return self.canonical(theta)

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.param_names, np.asarray(theta), strict=True)}

    def check(self, theta: np.ndarray, boundary_ok: bool = False) -> None:
        """Raise ModelError naming the first component whose parameters are out of domain.
        ``boundary_ok`` accepts a scale parameter (variance, amplitude, drift) of exactly 0."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (self.n_params,):
            raise ModelError(f"model {self.spec} has {self.n_params} parameters, got {theta.size}")
        for c in self.components:
            p = theta[c.slice].copy()
            if boundary_ok and p[c.process.scale_index] == 0:
                p[c.process.scale_index] = 1.0  # the boundary value 0: check the others only
            msg = c.process.check(p)
            if msg:
                raise ModelError(f"{c.name}: {msg}")

    def canonical(self, theta: np.ndarray) -> np.ndarray:
        """Relabel same-type components in order of the time scale they act on (shortest first)."""
        theta = np.array(theta, dtype=float)
        out = theta.copy()
        for name in PROCESSES:
            comps = [c for c in self.components if c.process.name == name]
            if len(comps) < 2:
                continue
            keys = [c.process.order_key(theta[c.slice], self.freq) for c in comps]
            for target, src in zip(comps, np.argsort(keys, kind="stable"), strict=True):
                out[target.slice] = theta[comps[src].slice]
        return out

    # -- theoretical wavelet variance -----------------------------------------------------------
    def component_wv(self, theta: np.ndarray, scales: np.ndarray) -> dict[str, np.ndarray]:
        """Theoretical WV of each component at filter lengths ``scales`` (samples)."""
        tau = np.asarray(scales, dtype=float)
        theta = np.asarray(theta, dtype=float)
        return {c.name: c.process.wv(theta[c.slice], tau, self.freq) for c in self.components}

    def wv(self, theta: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """Theoretical Haar WV of the model (sum over independent components)."""
        tau = np.asarray(scales, dtype=float)
        theta = np.asarray(theta, dtype=float)
        total = np.zeros_like(tau)
        for proc, sl in self._parts:  # the loop of component_wv, without its dictionary
            total += proc.wv(theta[sl], tau, self.freq)
        return total

    def wv_many(self, thetas: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """Theoretical WV for many parameter vectors at once: (N, p) -> (N, J). Vectorised over
        the rows (posterior sampling and grid scans call it with thousands of rows)."""
        TH = np.atleast_2d(np.asarray(thetas, dtype=float))
        tau = np.asarray(scales, dtype=float)
        out = np.zeros((TH.shape[0], tau.size))
        for proc, sl in self._parts:
            out += proc.wv_many(TH[:, sl], tau, self.freq)
        return out

    def canonical_many(self, thetas: np.ndarray) -> np.ndarray:
        """:meth:`canonical` applied to every row of ``thetas`` (N, p)."""
        TH = np.atleast_2d(np.asarray(thetas, dtype=float))
        out = TH.copy()
        for name in PROCESSES:
            comps = [c for c in self.components if c.process.name == name]
            if len(comps) < 2:
                continue
            keys = np.column_stack([[c.process.order_key(p, self.freq) for p in TH[:, c.slice]]
                                    for c in comps])
            order = np.argsort(keys, axis=1, kind="stable")
            blocks = np.stack([TH[:, c.slice] for c in comps], axis=1)  # (N, k, q)
            ordered = np.take_along_axis(blocks, order[:, :, None], axis=1)
            for i, c in enumerate(comps):
                out[:, c.slice] = ordered[:, i]
        return out

    def jacobian(self, theta: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """Analytic d nu_j / d theta, shape (J, n_params)."""
        tau = np.asarray(scales, dtype=float)
        theta = np.asarray(theta, dtype=float)
        jac = np.empty((tau.size, self.n_params))
        for proc, sl in self._parts:
            jac[:, sl] = proc.jacobian(theta[sl], tau, self.freq)
        return jac

    # -- simulation -----------------------------------------------------------------------------
    def simulate(self, theta: np.ndarray, n: int,
                 rng: np.random.Generator | int | None = None) -> np.ndarray:
        """One realisation of length ``n`` (float64), components drawn in canonical order."""
        theta = np.asarray(theta, dtype=float)
        self.check(theta)
        n = int(n)
        if n < 1:
            raise ModelError(f"number of samples must be positive, got {n}")
        rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        x = None
        for c in self.components:
            part = c.process.simulate(theta[c.slice], n, rng, self.freq)
            if x is None:  # each process returns a fresh array: the first one holds the sum
                x = part.astype(float, copy=False)
            else:
                x += part
        return x

    def simulate_fast(self, theta: np.ndarray, n: int,
                      rng: np.random.Generator | int | None = None,
                      block: int = 1 << 15, boundary_ok: bool = False) -> np.ndarray:
        """A realisation equal in distribution to :meth:`simulate`'s up to an additive constant,
        at a fraction of the cost (float64, length ``n``; the ratio per model is measured by
        ``benchmarks/bench_simulate.py``, table in ``benchmarks/README.md``). For Monte Carlo
        studies of shift-invariant statistics: the WV, the Allan variance and every fit ignore the
        constant.

        Differences from :meth:`simulate` (other random numbers for the same ``rng``):

        * all WN and RW components are one stream: x_t = a z_t + b sum_{k<t} z_k has increments
          a z_t + (b - a) z_{t-1}, an MA(1) with the variance (2 sigma2 + gamma2) and lag-1
          covariance (-sigma2) of the increments of WN + RW, so one normal per sample instead of
          two. The constant is the walk's start, which :meth:`simulate` draws at random.
        * the signal is built in blocks of ``block`` samples that stay in cache, one Numba pass
          per component (``gmwm._simkernels``).

        Stream, for reproducibility: first one normal per AR1/GM (its stationary start), one
        uniform per QN (its first level) and one per SIN (its phase), in component order; then
        per block ``block`` normals for the WN/RW stream (if any) and for each AR1/GM, and
        ``block`` uniforms for each QN, in that order. ``boundary_ok``: as in :meth:`check` (a
        component with scale parameter 0 contributes nothing).
        """
        from . import _simkernels as k  # Numba: loaded only by simulation

        theta = np.asarray(theta, dtype=float)
        self.check(theta, boundary_ok=boundary_ok)
        n = int(n)
        if n < 1:
            raise ModelError(f"number of samples must be positive, got {n}")
        rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        plan = self.simulation_plan(theta, rng)
        walk, omega, ar1, qn, sines = plan.walk, plan.omega, plan.ar1, plan.qn, plan.sines
        a_w, b_w, level = plan.a_w, plan.b_w, 0.0
        n_normal = int(walk) + len(ar1)
        z = np.empty((n_normal, min(block, n)))
        u = np.empty((len(qn), min(block, n)))
        x = np.empty(n)
        for start in range(0, n, block):
            xb = x[start:start + block]
            m = xb.size
            xb[:] = 0.0
            for i in range(n_normal):
                rng.standard_normal(out=z[i, :m])
            for i in range(len(qn)):
                rng.random(out=u[i, :m])
            i = 0
            if walk:
                level = k.add_walk_noise(xb, z[0, :m], a_w, b_w, level)
                i = 1
            for st in ar1:
                st[2] = k.add_ar1(xb, z[i, :m], st[0], st[1], st[2])
                i += 1
            for st, ub in zip(qn, u, strict=True):
                st[1] = k.add_quantization(xb, ub[:m], st[0], st[1])
            if omega:
                k.add_drift(xb, omega, start + 1)
            for alpha, beta, phase in sines:
                k.add_sinusoid(xb, alpha, beta, phase, start + 1)
        return x

    def simulation_plan(self, theta: np.ndarray, rng: np.random.Generator) -> SimulationPlan:
        """The components at ``theta`` in the primitive form the block simulators take
        (:meth:`simulate_fast`, :mod:`gmwm.fused`): WN and RW as one walk-plus-noise stream
        x_t = a z_t + b sum_{k<t} z_k, AR1/GM with their stationary start, QN with its first
        level, SIN with its phase; the start states drawn from ``rng`` in component order (one
        normal per AR1/GM, one uniform per QN and per SIN). ``theta`` is checked by the caller."""
        sigma2 = gamma2 = omega = 0.0
        ar1: list[list[float]] = []  # [phi, innovation sd, state]
        qn: list[list[float]] = []  # [q, previous uniform]
        sines: list[tuple[float, float, float]] = []  # (alpha, beta, phase)
        for c in self.components:
            kind, *v = c.process.primitive(theta[c.slice], self.freq)
            if kind == "wn":
                sigma2 += v[0]
            elif kind == "rw":
                gamma2 += v[0]
            elif kind == "dr":
                omega += v[0]
            elif kind == "ar1":
                phi, _, s2 = v
                s = math.sqrt(s2)
                ar1.append([phi, s, s * rng.standard_normal() / math.sqrt(1.0 - phi * phi)])
            elif kind == "qn":
                qn.append([math.sqrt(12.0 * v[0]), rng.random()])
            elif kind == "sin":
                sines.append((v[0], v[1], rng.uniform(0.0, 2 * np.pi)))
            else:  # a process added to PROCESSES without a kernel here
                raise ModelError(f"the block simulators have no kernel for process "
                                 f"{c.process.name!r}")
        walk = sigma2 > 0 or gamma2 > 0
        a_w = b_w = 0.0
        if walk:
            # increments a z_t + (b - a) z_{t-1}: an MA(1) with the variance (2 sigma2 + gamma2)
            # and lag-1 covariance (-sigma2) of the increments of WN + RW
            c0 = 2 * sigma2 + gamma2
            g = math.sqrt(gamma2 * (4 * sigma2 + gamma2))
            theta_ma = -2 * sigma2 / (c0 + g)  # invertible root of theta/(1 + theta^2) = -sigma2/c0
            a_w = math.sqrt(c0 / (1 + theta_ma * theta_ma))
            b_w = a_w * (gamma2 + g) / (c0 + g)  # a (1 + theta), free of cancellation
        return SimulationPlan(walk, a_w, b_w, omega, ar1, qn, sines)

    # -- unconstrained parametrisation ----------------------------------------------------------
    def to_free(self, theta: np.ndarray) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        return np.concatenate([c.process.to_free(theta[c.slice]) for c in self.components])

    def from_free(self, eta: np.ndarray) -> np.ndarray:
        return self._free.from_free(eta)

    def free_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Limits of the free coordinates (see ``Process.free_limits``)."""
        lims = [c.process.free_limits() for c in self.components]
        return np.concatenate([a for a, _ in lims]), np.concatenate([b for _, b in lims])

    def dtheta_deta(self, eta: np.ndarray) -> np.ndarray:
        """Diagonal of d theta / d eta (every transform acts on one parameter)."""
        return self._free.dp_deta(eta)


def as_model(model: str | Model, freq: float | None = None) -> Model:
    """Coerce a model string or Model to a Model (with ``freq`` if given)."""
    if isinstance(model, Model):
        return model if freq is None or freq == model.freq else Model(model.spec, freq)
    return Model(model, 1.0 if freq is None else freq)
