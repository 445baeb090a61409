"""A Pygments lexer for scene files: `pygmentize -l isaac scene.isaac`, and ```isaac blocks in documentation.

Registered by entry point (`pygments.lexers`: isaac = isaac_lang.highlight:IsaacLexer); only Pygments imports
this module, so the tool itself never needs Pygments. The token rules follow grammar/isaac.lark (its terminals
COMMENT, STRING, NUMBER, UNIT, TNAME, NAME); the word lists are the language's own and a test keeps them equal
to the front end's tables. The same rules, as a TextMate grammar, are in editors/vscode/.
"""
from __future__ import annotations

from pygments.lexer import RegexLexer, bygroups, words
from pygments.token import Comment, Error, Keyword, Name, Number, Operator, Punctuation, String, Whitespace

# the grammar's keywords (isaac_lang.syntax.KEYWORDS) and its other fixed words
KEYWORDS = ("scene", "let", "include", "material", "body", "constraint", "kind", "force", "wind", "sound",
            "camera", "light", "solver", "exclude", "collide", "part", "use",
            "for", "vary", "goal")
WORDS = ("in", "during", "from", "until", "on", "world", "keys")
# shapes, motions, solver plans, integrators and switches: words that stand for a choice
CHOICES = ("sphere", "box", "cylinder", "capsule", "plane", "mesh", "compound", "dynamic", "static", "kinematic",
           "dynamics", "procedural", "auto", "rk4", "euler", "midpoint", "dense", "sparse", "tree", "direct",
           "gauss_seidel", "projection", "baumgarte", "distant", "point", "spot", "ambient", "none", "inverse",
           "inverse_square", "linear", "cubic", "step", "true", "false", "yes", "no", "off", "always")
# every property of a block and every scene setting (isaac_lang.lower and lower_constraints tables)
PROPERTIES = ("air", "area", "at", "audio", "channels", "collide", "color", "compliance", "damping", "delay",
              "density", "direction", "distance", "drag", "falloff", "file", "force", "fov", "frames", "friction",
              "from", "gain", "gravity", "gust", "inertia", "integrator", "intensity", "iterations", "kinematic", "length",
              "linear", "listener", "look", "loss", "mass", "material", "modes", "normal", "orient", "play",
              "poisson", "projection", "radius", "rate", "rayleigh", "rest", "restitution", "roughness", "scale",
              "seed", "size", "speed", "spin", "spread", "stabilization", "stabilize", "step", "stiffness",
              "substeps", "texture", "time", "to", "tolerance", "torque", "toward", "turbulence", "up", "velocity", "wind",
              "young")
CONSTANTS = ("pi", "e", "tau", "t")
# grammar/isaac.lark's UNIT, without its trailing look-ahead (added where it is used)
_UNIT_WORD = r"(?:GPa|MPa|kPa|Pa|kHz|Hz|kg|km|cm|mm|um|ms|us|min|m|g|s|deg|rad|N|J|W|dB)"
UNIT = rf"{_UNIT_WORD}(?:\^?-?[0-9])?(?:[*/]{_UNIT_WORD}(?:\^?-?[0-9])?)*(?![A-Za-z0-9_])"
NUMBER = r"(?:\d+(?:\.\d+)?|\.\d+)(?:[eE][+-]?\d+)?"
TNAME = r"[A-Za-z_][A-Za-z0-9_]*(?:\{[A-Za-z0-9_+\-*/]+\}[A-Za-z0-9_]*)+"
NAME = r"[A-Za-z_][A-Za-z0-9_]*"


class IsaacLexer(RegexLexer):
    """Isaac scene files (.isaac)."""

    name = "Isaac"
    aliases = ["isaac"]
    filenames = ["*.isaac"]
    mimetypes = ["text/x-isaac"]
    url = "docs/language.md"

    tokens = {
        "root": [
            (r"\s+", Whitespace),
            (r"(#|//)[^\n]*", Comment.Single),
            (r'"[^"\n]*"', String.Double),
            # a number and its unit: `5 cm`, `9.81 m/s2`
            (rf"({NUMBER})([ \t]*)({UNIT})", bygroups(Number.Float, Whitespace, Keyword.Type)),
            (NUMBER, Number.Float),
            # a unit after a parenthesised value: `(0, 1, 0) m`
            (rf"(\))([ \t]*)({UNIT})", bygroups(Punctuation, Whitespace, Keyword.Type)),
            (words(KEYWORDS, suffix=r"(?![A-Za-z0-9_{])"), Keyword.Declaration),
            (words(WORDS, suffix=r"(?![A-Za-z0-9_{])"), Keyword),
            (TNAME, Name.Variable),
            (rf"{NAME}(?=[ \t]*\()", Name.Function),
            (words(CONSTANTS, suffix=r"(?![A-Za-z0-9_{])"), Name.Constant),
            (words(CHOICES, suffix=r"(?![A-Za-z0-9_{])"), Keyword.Constant),
            (words(PROPERTIES, suffix=r"(?![A-Za-z0-9_{])"), Name.Attribute),
            (NAME, Name),
            (r"\.\.", Operator),
            (r"[-+*/^=@:]", Operator),
            (r"[(){},.]", Punctuation),
            (r".", Error),
        ],
    }


__all__ = ["IsaacLexer"]
