"""What may be written where: the shapes and motions of a body, and the properties each block and scene setting
takes, each with what it means (the checker reads these tables; so do syntax errors, the typo finder, the
highlighter and the language server). Plain data: this module imports nothing of the front end."""

from __future__ import annotations

import functools

SHAPES = ("sphere", "box", "cylinder", "capsule", "plane", "mesh", "compound")
MOTIONS = ("dynamic", "static", "kinematic")

SETTINGS = {"time": "start .. end", "gravity": "acceleration vector", "frames": "output frame rate",
            "air": "air density (drag of bodies in still air and in the winds)",
            "seed": "seed of random things", "listener": "{ at, gain, delay }", "audio": "{ rate, channels }"}
SOLVER_PROPS = {"integrator": "rk4 | euler | midpoint", "step": "time step", "stabilize": "frequency",
                "damping": "damping ratio", "linear": "auto | dense | sparse | tree", "substeps": "procedural",
                "iterations": "procedural", "compliance": "procedural softness, m/N",
                "projection": "procedural: auto | direct | gauss_seidel",
                "stabilization": "dynamics: projection | baumgarte",
                "tolerance": "dynamics, rk4: local error of a step before it is taken again in substeps (0: off)"}
CAMERA_PROPS = {"at": "position", "look": "point looked at", "up": "up direction", "fov": "vertical field of view"}
LIGHT_PROPS = {"from": "where a distant light comes from", "at": "position", "to": "where it points",
               "intensity": "brightness", "color": "(r, g, b)"}
MATERIAL_PROPS = {"density": "kg/m3", "friction": "Coulomb coefficient", "restitution": "0..1",
                  "young": "Young's modulus", "poisson": "Poisson's ratio", "loss": "internal friction tan(phi)",
                  "rayleigh": "(alpha, beta)", "roughness": "surface height scale", "texture": "height profile file"}
BODY_PROPS = {"radius": "length", "length": "length along z", "size": "box edges", "normal": "plane normal",
              "file": "mesh file", "scale": "mesh scale", "mass": "kg", "density": "kg/m3",
              "inertia": "principal moments", "at": "its origin (a primitive's centre)", "orient": "orientation",
              "velocity": "initial velocity", "spin": "initial angular velocity", "material": "material name",
              "collide": "on | off", "wind": "on | off", "drag": "drag coefficient", "area": "area facing the wind",
              "modes": "((f, decay, gain), ...)",
              "kinematic": "START .. END: on its path then, dynamic before and after"}
WIND_PROPS = {"direction": "where the air goes", "from": "source point", "toward": "direction from the source",
              "speed": "m/s, may follow t or a breath", "falloff": "none | inverse | inverse_square",
              "distance": "reference distance of the falloff", "spread": "cone half-angle",
              "turbulence": "gust amplitude (relative)", "gust": "gust time scale", "air": "air density"}
SOUND_PROPS = {"play": "audio-graph expression", "gain": "linear gain or dB"}
LISTENER_PROPS = {"at": "position", "gain": "gain", "delay": "on | off"}
AUDIO_PROPS = {"rate": "sample rate", "channels": "1 or 2"}

PART_PROPS = {"radius": "length", "length": "length along the part's z", "size": "box edges", "file": "mesh file",
              "scale": "mesh scale", "mass": "kg", "density": "kg/m3", "at": "its origin, about the body's origin",
              "orient": "its orientation in the body", "material": "material name (default: the body's)",
              "modes": "((f, decay, gain), ...)"}
CONSTRAINT_PROPS = {"stabilize": "frequency", "damping": "damping ratio", "compliance": "procedural softness"}
FORCE_PROPS = {"stiffness": "N/m", "rest": "rest length", "damping": "N*s/m", "force": "N (may follow t)",
               "torque": "N*m (may follow t)"}


@functools.lru_cache(maxsize=1)
def property_names() -> frozenset:
    """Every name a block or a scene setting knows (a line may open with one of them legitimately)."""
    tables = (SETTINGS, SOLVER_PROPS, CAMERA_PROPS, LIGHT_PROPS, MATERIAL_PROPS, BODY_PROPS, WIND_PROPS, SOUND_PROPS,
              LISTENER_PROPS, AUDIO_PROPS, CONSTRAINT_PROPS, FORCE_PROPS, PART_PROPS)
    return frozenset(name for table in tables for name in table)
