"""The collision stage of the procedural plan: contacts at position level, in the spirit of its three steps.

The procedural step (runtime/procedural_plan.py) moves the bodies unconstrained and projects the joints; this
stage then, as for the dynamics plan (collider.py):
  1. finds the contacts at the new positions, and locates an impact inside the step by re-running the
     procedural step from the step's start for part of it (the stepper takes any step length);
  2. projects the positions out of interpenetration, mass-weighted through generalized inverse masses (a heavy
     body moves less, a contact off the centre turns the body), the joints kept to first order, and the
     velocities untouched: the projection adds no energy (response.py, `correct_positions`);
  3. gives the velocities restitution and friction with the same impulses, since the procedural plan's
     velocities (position change over the last substep) are the ones its next step starts from.
Without step 1 a procedural step of 1/60 s lets a ball of the cradle arrive 16 mm deep into the next one, and
projecting that apart moves the whole row.
"""
from __future__ import annotations

from .collider import Collider


class ProceduralCollider(Collider):
    def _integrate(self, tau: float, epoch) -> None:
        self.sim.procedural.step(self.sim.state, tau, epoch)
