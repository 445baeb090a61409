"""The clock (docs/clock.md): its beat, the pendulum's angle and the escape wheel's over the scene's 30 s and three
periods close up with the ticks (the impacts of events), in clock.png; and the escapement itself, the parts of the
wheel and the anchor in the wheel's plane at four moments of one swing, in clock_escapement.png.
Run: python docs/figures/make_clock_figure.py"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from isaac_lang.load import load_scene
from isaac_runtime.core.rotation import quat_to_matrix
from isaac_runtime.run import RunOptions, simulate

ROOT = Path(__file__).resolve().parents[2]
CLOSE_UP = (20.0, 23.0)  # seconds
# one swing to the left, through a tick on the right pallet: locked, unlocked, pushing, just landed (seconds)
MOMENTS = (19.95, 20.13, 20.18, 20.26)
# the wheel's plane: parts whose centre lies within this of z = 0 (the rod, bob and arms are behind or before it)
PLANE = 0.0045  # m


def turn_about_z(frames, name: str) -> np.ndarray:
    """A body's angle about world z in degrees, unwrapped (the clock's bodies turn about z only)."""
    q = frames["orientation"][:, list(frames["bodies"]).index(name)]
    return np.degrees(np.unwrap(2.0 * np.arctan2(q[:, 3], q[:, 0])))


def outline(part) -> np.ndarray:
    """(k,3) the outline of a box or sphere part in the plane z = 0 of its own frame."""
    if part.shape.type == "sphere":
        turn = np.linspace(0.0, 2.0 * np.pi, 40)
        return part.shape.radius * np.stack([np.cos(turn), np.sin(turn), 0.0 * turn], axis=1)
    corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [-1, -1, 0]], float)
    return corners * np.asarray(part.shape.size) / 2


def draw_parts(axes, scene, frames, k: int) -> None:
    """The wheel's and the anchor's parts in the wheel's plane at frame k, in mm."""
    names = list(frames["bodies"])
    for body, colour in (("escape", "tab:red"), ("pendulum", "tab:blue")):
        declared = next(b for b in scene.bodies if b.name == body)
        i = names.index(body)
        centre, turn = frames["position"][k, i], quat_to_matrix(frames["orientation"][k, i])
        for part in declared.shape.parts:
            if part.shape.type not in ("box", "sphere") or abs(part.position[2]) > PLANE:
                continue
            # a part's world points: x + R (offset + p + R_part c)
            local = np.asarray(part.position) + outline(part) @ quat_to_matrix(np.asarray(part.orientation)).T
            world = centre + (np.asarray(declared.shape.offset) + local) @ turn.T
            axes.plot(world[:, 0] * 1000, world[:, 1] * 1000, color=colour, lw=0.8)


def draw_escapement(scene, frames, figure_path: Path) -> None:
    """Each pallet and the teeth near it (rows: left, right) at MOMENTS (columns)."""
    figure, panels = plt.subplots(2, len(MOMENTS), figsize=(2.6 * len(MOMENTS), 5.6))
    for column, moment in enumerate(MOMENTS):
        k = int(np.argmin(np.abs(frames["time"] - moment)))
        for row, xs in enumerate(((-42, -28), (28, 42))):
            axes = panels[row, column]
            draw_parts(axes, scene, frames, k)
            axes.set_aspect("equal")
            axes.set_xlim(*xs)
            axes.set_ylim(28, 42)
            axes.tick_params(labelsize=7)
        panels[0, column].set_title(f"t = {frames['time'][k]:.2f} s", fontsize=9)
    panels[0, 0].set_ylabel("left pallet, y (mm)", fontsize=8)
    panels[1, 0].set_ylabel("right pallet, y (mm)", fontsize=8)
    figure.suptitle("one swing to the left: locked on the left, unlocked, the push, the tick on the right "
                    "(wheel red, anchor blue; x, y in mm)", fontsize=9)
    figure.tight_layout()
    figure.savefig(figure_path, dpi=110)


def main() -> None:
    scene = load_scene(ROOT / "scenes" / "clock.isaac").scene
    result = simulate(scene, RunOptions(folder=ROOT / "scenes"))
    frames = result.recorder.arrays()
    draw_escapement(scene, frames, Path(__file__).with_name("clock_escapement.png"))
    t, pendulum, wheel = frames["time"], turn_about_z(frames, "pendulum"), turn_about_z(frames, "escape")
    ticks = [e["time"] for e in result.simulation.events if e["kind"] == "impact"]
    figure, (whole, close) = plt.subplots(2, 1, figsize=(8, 6))
    for axes, span in ((whole, (t[0], t[-1])), (close, CLOSE_UP)):
        shown = (t >= span[0]) & (t <= span[1])
        axes.plot(t[shown], pendulum[shown], color="tab:blue", lw=1)
        axes.set_ylabel("pendulum (deg)", color="tab:blue")
        other = axes.twinx()
        other.plot(t[shown], -wheel[shown], color="tab:red", lw=1)
        other.set_ylabel("escape wheel, clockwise (deg)", color="tab:red")
        axes.set_xlim(*span)
    for tick in ticks:
        if CLOSE_UP[0] <= tick <= CLOSE_UP[1]:
            close.axvline(tick, color="0.6", lw=0.6, ls=":")
    whole.set_title("Eli Terry's clock: 30 teeth, deadbeat anchor, RK4 1 ms")
    close.set_xlabel("time (s); dotted: the ticks (a tooth dropping onto a pallet)")
    figure.tight_layout()
    figure.savefig(Path(__file__).with_name("clock.png"), dpi=110)


if __name__ == "__main__":
    main()
