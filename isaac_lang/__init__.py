"""isaac_lang: the front end. Scene text -> parse tree -> expanded declarations -> IR (isaac_ir) -> checked IR."""

from isaac_ir.imports import without as _without

# lark imports interegular, when it is installed, only to warn about colliding terminals while it builds a lexer:
# 40 ms of every command's start, for a check that belongs to writing a grammar, not to reading scenes; and regex,
# which it needs only for Unicode categories (\p{...}) in a grammar's terminals, which ours has none of (25 ms)
with _without("interegular", "regex", why="lark"):
    import lark  # noqa: E402,F401
