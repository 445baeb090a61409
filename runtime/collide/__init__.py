"""Collisions and impacts (docs/design/physics.md section 5): the collision plan, compiled once per scene.

    compile_collisions(scene, plan) -> CollisionPlan | None      None: no pair can ever touch (no stage at all)
    CollisionPlan.start(simulation) -> the run's stage, with before_step(h, epoch) and after_step(h, epoch)

The package, one stage per file:
    shapes.py     collision geometry of every body, bounding boxes
    pairs.py      exclusion (once) and the sort-and-sweep broad phase (every step)
    narrow.py     closed-form contact tests (spheres, capsules, cylinders, planes; boxes.py: boxes)
    meshes.py     OBJ/STL meshes and every pair without a closed form, through python-fcl (imported only then)
    response.py   impulses solved with the joint rows, impacts in generations, friction, position correction
    lcp.py        the contact problem (direct solve, then projected Gauss-Seidel)
    collider.py   the stage of the dynamics plan: scan, time of impact, resolve
    events.py     contact events for events.json and the audio graph
docs/collisions.md says how it behaves and where its limits are.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from isaac_ir.diagnostics import counted

from ..signals import asset_folders
from .narrow import needs_fcl
from .pairs import count_pairs, excluded_keys, exclusion_pairs, pair_keys
from .shapes import KIND_NAMES
from .table import build_table

COMPOUND = -2  # the plan's count of compound bodies (not a shape kind of the table)

# contacts are kept (and act) while the surfaces are up to this far apart, m; boxes grow by it in the broad phase
CONTACT_MARGIN = 1e-4
# friction and restitution of a body without a material (the language's material defaults)
DEFAULT_FRICTION = 0.5
DEFAULT_RESTITUTION = 0.5


@dataclass
class CollisionPlan:
    """What is decided once: which bodies collide, their geometry and materials, which pairs are excluded.

    collidable (c,) body indices; excluded: sorted pair keys i * n + j of excluded pairs; pairs: how many pairs
    can touch; reasons: how many were excluded and why; friction, restitution, has_material (bool) of each body,
    then of each part of the compound bodies (table.elements); fcl_bodies: bodies that go through
    python-fcl (empty: fcl is never imported), fcl_elements their shapes (indices of table.elements when there
    are compound bodies); margin (m)."""

    table: object
    collidable: np.ndarray
    excluded: np.ndarray  # the pairs excluded for the whole run (the broad phase's, at the start)
    pairs: int
    reasons: dict
    friction: np.ndarray
    restitution: np.ndarray
    has_material: np.ndarray
    fcl_bodies: np.ndarray
    margin: float
    kinds: dict
    windows: tuple = ()  # ((start, end, keys), ...): the pairs an `exclude` with a window excludes in it
    fcl_elements: np.ndarray | None = None  # what python-fcl holds: fcl_bodies, or (compound bodies) elements
    # `collide`: the pairs it names for the whole run (keys), and ((start, end, keys), ...) of those with a window
    restored: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    collide_windows: tuple = ()
    # the pairs joined for the whole run that only a windowed `collide` names: excluded outside its window
    suspended: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    restored_pairs: int = 0  # how many pairs joined by a constraint (at some time) a `collide` gives back

    @property
    def always_excluded(self) -> np.ndarray:
        return self.excluded

    def excluded_at(self, t: float) -> np.ndarray:
        """The keys of the pairs a windowed `exclude` excludes at time t."""
        keys = [k for start, end, k in self.windows if start <= t < end]
        return np.unique(np.concatenate(keys)) if keys else np.zeros(0, np.int64)

    def restored_at(self, t: float) -> np.ndarray:
        """The keys of the pairs a `collide` names at time t (they collide even while a constraint joins them)."""
        keys = [self.restored] + [k for start, end, k in self.collide_windows if start <= t < end]
        return np.unique(np.concatenate(keys)).astype(np.int64)

    def excluded_now(self, joined: np.ndarray, t: float) -> np.ndarray:
        """Sorted keys of the pairs that do not collide at t, given the keys of the pairs joined by the
        constraints on now: those excluded for the whole run, those a windowed `exclude` names now, and the joined
        ones (with those joined for the whole run that a windowed `collide` names) unless a `collide` names them
        now. (A `collide` and an `exclude` of one pair at overlapping times is an error of the scene.)"""
        keys = np.union1d(self.always_excluded, self.excluded_at(t))
        held = np.union1d(np.asarray(joined, np.int64), self.suspended)
        held = np.setdiff1d(held, self.restored_at(t))
        return np.union1d(keys, held).astype(np.int64)

    def phase(self, t: float) -> bytes:
        """What changes the pairs excluded at t apart from the epoch: the windowed `exclude`s and `collide`s on."""
        return self.excluded_at(t).tobytes() + b"|" + self.restored_at(t).tobytes()

    def window_switches(self) -> list:
        """The times a windowed exclusion (or a windowed `collide`) begins or ends."""
        return sorted({float(v) for start, end, _ in self.windows + self.collide_windows for v in (start, end)
                       if np.isfinite(v)})

    def start(self, simulation):
        from .collider import Collider

        return Collider(self, simulation)

    def mix(self, a, b):
        """Friction and restitution of contacts between elements a and b (k,) (bodies, or the parts of compound
        bodies: compound.contact_elements): friction sqrt(mu_a mu_b),
        restitution max(e_a, e_b) (Box2D's rules); a body without a material takes the other's values, two
        without take the defaults."""
        ha, hb = self.has_material[a], self.has_material[b]
        mu = np.where(ha & hb, np.sqrt(self.friction[a] * self.friction[b]),
                      np.where(ha, self.friction[a], np.where(hb, self.friction[b], DEFAULT_FRICTION)))
        e = np.where(ha & hb, np.maximum(self.restitution[a], self.restitution[b]),
                     np.where(ha, self.restitution[a], np.where(hb, self.restitution[b], DEFAULT_RESTITUTION)))
        return mu, e

    def describe(self) -> str:
        kinds = ", ".join(f"{KIND_NAMES.get(k, 'compound')} x{c}" for k, c in sorted(self.kinds.items()) if k != -1)
        narrow = "closed forms" + (f" + python-fcl ({len(self.fcl_bodies)} bodies)" if len(self.fcl_bodies) else "")
        reasons = ", ".join(f"{v} {k}" for k, v in self.reasons.items() if v)
        n = self.restored_pairs
        restored = f"; {n} joined pair{'s' if n != 1 else ''} restored by `collide`" if n else ""
        return (f"collisions: {counted(len(self.collidable), 'body')} ({kinds}), {counted(self.pairs, 'pair')} can touch"
                f"{' (excluded: ' + reasons + ')' if reasons else ''}{restored}; narrow phase: {narrow}")


def compile_collisions(scene, plan, folder=None) -> CollisionPlan | None:
    """The collision plan, or None when every pair of collidable bodies is excluded."""
    collidable = np.array([i for i, b in enumerate(scene.bodies) if b.collide], np.int64)
    dynamic = plan.dynamic
    keys = excluded_keys(scene, plan, collidable)
    excluded = np.union1d(keys["joined"], keys["excluded"])
    pairs = count_pairs(collidable, dynamic, excluded)
    if pairs <= 0:
        return None
    # a mesh is named relative to the scene's folder: the plan's when it knows it, else searched for (signals.py)
    folders = asset_folders(scene, folder if folder is not None else getattr(plan, "folder", None))
    table = build_table(scene, [int(i) for i in collidable], folders)
    compound = np.array([scene.bodies[i].shape.type == "compound" for i in collidable], bool)
    kinds = np.where(compound, -1, table.kind[collidable])  # a compound's parts are looked at below
    fcl_kinds = _kinds_needing_fcl(kinds, collidable, dynamic, excluded, len(scene.bodies))
    fcl_bodies = collidable[np.isin(kinds, list(fcl_kinds))] if fcl_kinds else np.zeros(0, np.int64)
    fcl_parts = fcl_bodies
    if table.elements is not None:
        from .compound import fcl_elements

        touchable = _touchable_pairs(collidable[compound], collidable, dynamic, excluded, len(scene.bodies))
        fcl_parts = np.union1d(fcl_bodies, fcl_elements(scene, table, table.elements, touchable)).astype(np.int64)
        fcl_bodies = np.unique(table.elements.owner[fcl_parts]).astype(np.int64)
    friction, restitution, has = _materials(scene, table.elements)
    still = int(np.count_nonzero(~dynamic[collidable]))
    reasons = {"joined by a constraint": len(keys["joined"]),
               "by `exclude`": len(np.setdiff1d(keys["excluded"], keys["joined"])),
               "neither dynamic": still * (still - 1) // 2}
    counted = {int(k): int(c) for k, c in zip(*np.unique(kinds, return_counts=True))}
    if compound.any():
        counted[COMPOUND] = int(compound.sum())
    index = scene.body_index()
    windows = tuple((ex.start, ex.end, pair_keys(np.array(exclusion_pairs(ex, index), np.int64).reshape(-1, 2),
                                                 len(scene.bodies)))
                    for ex in scene.exclusions if ex.start > plan.start or ex.end < plan.end)
    collides = getattr(scene, "collides", ())
    whole = [p for c in collides if c.start <= plan.start and c.end >= plan.end for p in exclusion_pairs(c, index)]
    whole = np.unique(pair_keys(np.array(whole, np.int64).reshape(-1, 2), len(scene.bodies)))
    collide_windows = tuple((c.start, c.end, pair_keys(np.array(exclusion_pairs(c, index), np.int64).reshape(-1, 2),
                                                       len(scene.bodies)))
                            for c in collides if c.start > plan.start or c.end < plan.end)
    return CollisionPlan(table, collidable, excluded, pairs, reasons, friction, restitution, has, fcl_bodies,
                         CONTACT_MARGIN, counted, windows, fcl_parts, whole.astype(np.int64), collide_windows,
                         keys["suspended"], len(keys["restored"]))


def _touchable_pairs(compounds, collidable, dynamic, excluded, n) -> np.ndarray:
    """(k,2) the pairs of a compound body with another collidable body that can touch (not both unable to move,
    not excluded for the whole run)."""
    pairs = np.array([(min(c, o), max(c, o)) for c in compounds.tolist() for o in collidable.tolist() if o != c],
                     np.int64).reshape(-1, 2)
    pairs = np.unique(pairs, axis=0)
    keep = (dynamic[pairs[:, 0]] | dynamic[pairs[:, 1]]) & ~np.isin(pair_keys(pairs, n), excluded)
    return pairs[keep]


def _kinds_needing_fcl(kinds, collidable, dynamic, excluded, n) -> set:
    """Shape kinds that meet, in at least one pair that can touch, a kind with no closed-form test."""
    needed = set()
    present = sorted(k for k in set(kinds.tolist()) if k >= 0)  # (-1: a compound body, whose parts count)
    for ka, kb in itertools.combinations_with_replacement(present, 2):
        if not needs_fcl(ka, kb):
            continue
        ia, ib = collidable[kinds == ka], collidable[kinds == kb]
        total = len(ia) * len(ib) if ka != kb else len(ia) * (len(ia) - 1) // 2
        sa, sb = int((~dynamic[ia]).sum()), int((~dynamic[ib]).sum())
        still = sa * sb if ka != kb else sa * (sa - 1) // 2
        i, j = excluded // n, excluded % n
        kind_of = np.full(n, -1)
        kind_of[collidable] = kinds
        gone = int(np.count_nonzero(((kind_of[i] == ka) & (kind_of[j] == kb)) | ((kind_of[i] == kb) & (kind_of[j] == ka))))
        if total - still - gone > 0:
            needed |= {ka, kb}
    return needed


def _materials(scene, elements=None):
    """friction, restitution, has_material of every element: the bodies, then the parts (each its own material,
    or its body's)."""
    n = len(scene.bodies)
    owners = [body.material for body in scene.bodies]
    if elements is not None:
        owners += [scene.bodies[int(elements.owner[e])].shape.parts[int(elements.index[e])].material
                   for e in range(n, len(elements.owner))]
    materials = {m.name: m for m in scene.materials}
    friction, restitution, has = np.zeros(len(owners)), np.zeros(len(owners)), np.zeros(len(owners), bool)
    for i, name in enumerate(owners):
        if name in materials:
            m = materials[name]
            friction[i], restitution[i], has[i] = m.friction, m.restitution, True
    return friction, restitution, has
