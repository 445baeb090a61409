"""MuJoCo models of the mechanisms (MJCF written in code) and a runner that yields our trajectory dict.

Settings that would spoil the comparison, set explicitly (MuJoCo 3.x/4.x defaults in brackets):
- equality constraints are soft: solref = (2 h, 1), the stiffest time constant MuJoCo accepts (it raises any
  smaller one to 2 steps) [0.02 s, 1]; solimp = (0.9999, 0.9999, 0.001) [0.9, 0.95, 0.001]: impedance as
  close to a hard constraint as it allows;
- the self-assembly tie uses solref's direct form (-ks, -kd), so that the constraint follows our Baumgarte
  curve d2C/dt2 + kd dC/dt + ks C = 0 (2 Hz, critically damped);
- solver Newton, tolerance 1e-12 [1e-8], 100 iterations; no contacts (flag contact="disable"); no damping,
  armature or friction loss (the defaults, written out); inertia given, never from geometry;
- integrator Euler (semi-implicit) or RK4, matching ours (euler, rk4) at equal step.
"""
from __future__ import annotations

import numpy as np

from .mechanisms import Mechanism

SOLIMP = "0.9999 0.9999 0.001 0.5 2"
INTEGRATORS = {"euler": "Euler", "rk4": "RK4", "implicitfast": "implicitfast"}


def available() -> bool:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        return False
    return True


def _v(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def _inertial(m: Mechanism, name: str) -> str:
    i = m.index(name)
    diag = np.diag(m.physics.inertia[i])
    return f'<inertial pos="0 0 0" mass="{m.physics.mass[i]:.17g}" diaginertia="{_v(diag)}"/>'


JOINT_TYPES = {"ball": "mjJNT_BALL", "hinge": "mjJNT_HINGE", "slide": "mjJNT_SLIDE"}


def _add_reduced_bodies(spec, m: Mechanism) -> None:
    """Each jointed body nested in its parent, position relative to the parent, joint at its anchor. Built with
    MjSpec rather than XML: a 1000-link chain is 1000 levels deep, beyond the XML parser's nesting limit."""
    import mujoco

    parent = m.parent_of()
    joints = {j.body: j for j in m.joints}
    made = {}
    for name in m.order():
        up = parent[name]
        origin = m.x0(up) if up else np.zeros(3)
        x = m.x0(name)
        body = (made[up] if up else spec.worldbody).add_body(name=name, pos=list(x - origin))
        i = m.index(name)
        body.mass, body.inertia, body.ipos = float(m.physics.mass[i]), list(np.diag(m.physics.inertia[i])), [0, 0, 0]
        body.explicitinertial = True
        j = joints[name]
        body.add_joint(name=f"j_{name}", type=getattr(mujoco.mjtJoint, JOINT_TYPES[j.kind]),
                       pos=list(np.asarray(j.anchor, float) - x) if j.kind != "slide" else [0, 0, 0], axis=list(j.axis),
                       damping=0.0, armature=0.0, frictionloss=0.0)
        made[name] = body


def _equality_xml(m: Mechanism, h: float, reduced: bool) -> tuple:
    """(sites to add per body, <equality> body, indices of ties that start later)."""
    sites: dict = {}
    eqs, late = [], []
    if reduced:
        for c in m.couplings:
            eqs.append(f'<joint joint1="j_{c.a}" joint2="j_{c.b}" polycoef="0 {c.ratio:.17g} 0 0 0" '
                       f'solref="{2 * h:.17g} 1" solimp="{SOLIMP}"/>')
        return sites, "".join(eqs), late
    for k, tie in enumerate(m.maximal_ties()):
        sites.setdefault(tie.a, []).append(f'<site name="s{k}a" pos="{_v(tie.point_a)}"/>')
        sites.setdefault(tie.b, []).append(f'<site name="s{k}b" pos="{_v(tie.point_b)}"/>')
        if tie.gains is not None:
            # direct stiffness and damping: MuJoCo scales them by the impedance so that the constraint follows
            # C'' + kd C' + ks C = 0 (checked: the curve matches to 3e-10 of the gap at h = 0.1 ms with RK4)
            ref = f"{-tie.gains[0]:.17g} {-tie.gains[1]:.17g}"
        else:
            ref = f"{2 * h:.17g} 1"
        active = "false" if tie.start > 0 else "true"
        eqs.append(f'<connect site1="s{k}a" site2="s{k}b" active="{active}" solref="{ref}" solimp="{SOLIMP}"/>')
        if tie.start > 0:
            late.append((k, tie.start))
    return sites, "".join(eqs), late


def build(m: Mechanism, formulation: str, integrator: str, h: float):
    """(MjModel, MjData, body ids in our body order, late ties [(equality id, start time)])."""
    import mujoco

    reduced = formulation == "reduced"
    sites, equality, late = _equality_xml(m, h, reduced)
    if reduced:
        bodies = ""  # added through MjSpec below
    else:
        bodies = "".join(f'<body name="{n}" pos="{_v(m.x0(n))}"><freejoint/>{_inertial(m, n)}'
                         f'{"".join(sites.get(n, []))}</body>' for n in m.physics.names if m.physics.dynamic[m.index(n)])
    world_sites = "".join(sites.get(None, []))
    xml = (f'<mujoco><option timestep="{h:.17g}" integrator="{INTEGRATORS[integrator]}" gravity="{_v(m.gravity)}" '
           f'solver="Newton" iterations="100" tolerance="1e-12"><flag contact="disable"/></option>'
           f'<worldbody>{world_sites}{bodies}</worldbody><equality>{equality}</equality></mujoco>')
    spec = mujoco.MjSpec.from_string(xml)
    if reduced:
        _add_reduced_bodies(spec, m)
    model = spec.compile()
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in m.physics.names]
    mujoco.mj_forward(model, data)
    return model, data, ids, late


class Runner:
    """Steps a built model; `sample()` reads the state of our bodies (static ones: id -1, left at rest)."""

    def __init__(self, m: Mechanism, formulation: str, integrator: str, h: float):
        import mujoco

        self.mj = mujoco
        self.model, self.data, self.ids, self.late = build(m, formulation, integrator, h)
        self.h, self.x0 = h, m.physics.x0
        self._vel = np.zeros(6)

    def advance(self, steps: int, probe=None, every: int = 1) -> None:
        mj, model, data = self.mj, self.model, self.data
        for k in range(1, steps + 1):
            for eq, start in self.late:
                if not data.eq_active[eq] and data.time >= start - 0.5 * self.h:
                    data.eq_active[eq] = 1
            mj.mj_step(model, data)
            if probe is not None and k % every == 0:
                probe.record(*self.sample())

    def sample(self):
        data, n = self.data, len(self.ids)
        x, q, v, w = self.x0.copy(), np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))
        for i, body in enumerate(self.ids):
            if body < 0:
                continue
            x[i] = data.xipos[body]
            q[i] = data.xquat[body]  # body frame = inertial frame here (inertial pos 0, no rotation)
            self.mj.mj_objectVelocity(self.model, data, self.mj.mjtObj.mjOBJ_BODY, body, self._vel, 0)
            w[i], v[i] = self._vel[:3], self._vel[3:]
        return data.time, x, q, v, w

    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.data.qpos)) and np.all(np.isfinite(self.data.qvel)))
