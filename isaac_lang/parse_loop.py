"""Stage 1, the hot loop of parsing: lark's contextual lexer and LALR(1) tables, driven by one function.

lark spends most of a parse in its own plumbing rather than in the grammar: a generator, a lexer object and a
parser-state object per token, a method call per regex match, a hash of a `Rule` per reduce, two or three
calls to build a tree, and, to give trees positions, a wrapper per reduce that inspects the children.
`ParseLoop` reads the tables lark built from grammar/isaac.lark (the regex of each state of the contextual
lexer, the keyword callbacks, the shift/reduce/goto table, the rules) and runs them in one loop with local
variables: the same tokens, the same trees, the positions lark's `propagate_positions=True` gives, in 40% of
the time lark takes without positions (a quarter of its time with them). On top of that: a token and the
blanks after it are one regex match; the seven pass-through reduces a number goes through (`?expr: sum`, ...)
are one look-up; a `_rule` is a list, not a tree; positions are a (first, last) token pair per tree, read when
asked. `_parse` is one long function on purpose: a Python call per token costs about what a shift costs.

It only parses what lark parses. A text it cannot take (no token matches, no action for a token) raises
`Rejected`, and the caller parses that text again with lark itself, which raises the exception, expected
terminals and position that syntax errors are described from: one grammar, one source of error messages.
tests/lang/test_parse_loop.py checks on the scenes and on fuzzed texts that both give the same trees, tokens
and positions, or both reject.
"""
from __future__ import annotations

import re

from lark import Lark, Token, Tree
from lark.lexer import UnlessCallback
from lark.parsers.lalr_analysis import Shift

_new = object.__new__  # trees are made without their Python-level __init__ (the loop fills them)
_new_token = str.__new__
PASS = "pass"  # the name of a `?rule: child` reduction, which leaves its child as it is


class Rejected(Exception):
    """The text is not in the language: ask lark for the syntax error."""


class Span(tuple):
    """The positions of a tree, as lark's `propagate_positions` gives them in its `meta`: from the first to the
    last token of the text it was parsed from, keywords and brackets included. A (first, last) pair of tokens,
    read when asked."""

    __slots__ = ()
    empty = False

    @property
    def line(self) -> int:
        return self[0].line

    @property
    def column(self) -> int:
        return self[0].column

    @property
    def start_pos(self) -> int:
        return self[0].start_pos

    @property
    def end_line(self) -> int:
        return self[1].end_line

    @property
    def end_column(self) -> int:
        return self[1].end_column

    @property
    def end_pos(self) -> int:
        return self[1].end_pos


class ParseLoop:
    """An LALR(1) parse with the tables of a Lark (`parser="lalr"`, contextual lexer, maybe_placeholders)."""

    def __init__(self, lark: Lark):
        frontend = lark.parser
        table = frontend.parser._parse_table
        self.start_states, self.end_states = table.start_states, table.end_states
        self.ignore = frozenset(lark.lexer_conf.ignore)
        self.newline = frontend.lexer.root_lexer.newline_types  # terminals that may hold a "\n"
        # the blanks after a token are matched with it (every state would skip them next: no other terminal
        # of this grammar starts with a blank), which halves the regex matches
        (blanks,) = [t.pattern.to_regexp() for t in lark.terminals if t.name == "WS" and t.name in self.ignore]
        self._table, self._lexers, self._blanks = table.states, frontend.lexer.lexers, blanks
        self._scanners, self._reductions = {}, {}
        # state -> (actions, match, keywords): actions maps a terminal to the next state (a shift) or to a
        # reduction (`_reduction`), and a rule's name to the state after it (the goto); each state's is made
        # when a parse first comes to it (`_state`: a scene comes to about two thirds of the lexer's states, and
        # making one compiles its regex, most of the time of making them all)
        self.states = _States(self._state)
        self.gotos = {}  # (state below, rule, terminal) -> the state after the goto (see `_goto`)

    def _state(self, state: int) -> tuple:
        """(actions, match, keywords) of one LALR state (`states` above)."""
        lexer = self._lexers[state]
        if id(lexer) not in self._scanners:
            self._scanners[id(lexer)] = _scanner(lexer, self._blanks)
        actions = {}
        for symbol, (kind, rule) in self._table[state].items():
            if kind is Shift:
                actions[symbol] = rule
            else:
                if id(rule) not in self._reductions:
                    self._reductions[id(rule)] = _reduction(rule)
                actions[symbol] = self._reductions[id(rule)]
        return (actions,) + self._scanners[id(lexer)]

    def parse(self, text: str, start: str = "start"):
        """The tree of `text` from rule `start`; raises Rejected where lark would raise a syntax error."""
        try:
            return self._parse(text, start)
        except KeyError:  # a terminal that the table has no action for in the state it comes in
            raise Rejected from None

    def _parse(self, text: str, start: str):
        states, ignore, newline, gotos = self.states, self.ignore, self.newline, self.gotos
        state, end_state = self.start_states[start], self.end_states[start]
        # the stacks: LALR states, values (tokens, trees), and the (first, last) token of each value's text
        state_stack, value_stack, span_stack = [state], [], []
        pos, line, line_start, size = 0, 1, 0, len(text)
        actions, match, keywords = states[state]
        while True:
            # -- lex a token and the blanks after it with the regex of the state (lark's line arithmetic) --
            if pos < size:
                found = match(text, pos)
                if found is None:
                    raise Rejected
                kind = found.lastgroup
                end, after = found.end(kind), found.end()  # the token, and the blanks after it
                if kind in ignore:
                    value = found.group()
                    if "\n" in value:
                        line += value.count("\n")
                        line_start = pos + value.rindex("\n") + 1
                    pos = after
                    continue
                value = text[pos:end]
                if kind == "NAME" and keywords is not None:
                    kind = keywords.get(value, kind)  # `scene`, `let`, ... where the state takes them
                token = _new_token(Token, value)
                token.type = kind
                token.value = value
                token.start_pos = pos
                token.end_pos = end
                token.line = line
                token.column = pos - line_start + 1
                if kind in newline and "\n" in value:
                    line += value.count("\n")
                    line_start = pos + value.rindex("\n") + 1
                token.end_line = line
                token.end_column = end - line_start + 1
                if after != end:
                    newlines = text.count("\n", end, after)
                    if newlines:
                        line += newlines
                        line_start = text.rindex("\n", end, after) + 1
                pos = after
            else:
                kind, token = "$END", None
            # -- reduce while the table says so, then shift the token (or accept at the end) ---------------
            while True:
                arg = actions[kind]
                if type(arg) is int:  # shift
                    if token is None:
                        raise Rejected
                    state = arg
                    state_stack.append(state)
                    value_stack.append(token)
                    span_stack.append((token, token))
                    break
                length, rule, keep, name, single = arg
                if name is PASS:  # `?rule: child` passes its child through: its value and span stay
                    del state_stack[-1]
                else:
                    if length == 1:  # (half of the reduces: a number, a name; the value replaces its child)
                        children = [value_stack.pop()]
                        span = span_stack.pop()
                        if span is not None and type(span) is not Span:
                            span = Span(span)
                        del state_stack[-1]
                    elif length:
                        children = value_stack[-length:]
                        head = span_stack[-length]
                        tail = span_stack[-1]
                        span = Span((head[0], tail[1])) if head and tail else _span(span_stack[-length:])
                        del state_stack[-length:], value_stack[-length:], span_stack[-length:]
                    else:
                        children, span = [], None
                    if keep is not None:
                        children = keep(children)
                    if name is None:  # a `_rule`: its children, which the rule above takes in
                        value = children
                    elif single and len(children) == 1:  # a `?rule` left with one child: that child
                        value = children[0]
                    else:
                        value = _new(Tree)
                        value.data = name
                        value.children = children
                        value._meta = span
                    value_stack.append(value)
                    span_stack.append(span)
                # the goto, and the pass-through reduces the same token then makes (a number goes through
                # seven: `?expr: sum`, `?sum: product`, ...), looked up at once
                key = (state_stack[-1], rule, kind)
                state = gotos.get(key)
                if state is None:
                    state = gotos[key] = self._goto(*key, end_state)
                state_stack.append(state)
                actions = states[state][0]
                if token is None and state == end_state:
                    return value_stack[-1]
            actions, match, keywords = states[state]

    def _goto(self, below: int, rule: str, kind: str, end_state: int) -> int:
        """The state after reducing to `rule` over state `below`, and after the pass-through reduces that
        terminal `kind` then makes (each reduces to a rule over the same `below`)."""
        state = self.states[below][0][rule]
        while state != end_state:
            arg = self.states[state][0].get(kind)
            if type(arg) is not tuple or arg[3] is not PASS:
                break  # a shift, a reduce that builds, or an error: the loop takes it from here
            state = self.states[below][0][arg[1]]
        return state


class _States(dict):
    """A dictionary whose entry for a key missing from it is made (by `make(key)`) and kept when first asked for;
    a key it already holds is found at the speed of a plain dictionary's."""

    def __init__(self, make):
        super().__init__()
        self._make = make

    def __missing__(self, key):
        entry = self[key] = self._make(key)
        return entry


def _span(spans: list) -> tuple | None:
    """The (first, last) token of a reduce's text from its children's, skipping children with no text."""
    texts = [span for span in spans if span is not None]
    return Span((texts[0][0], texts[-1][1])) if texts else None


def _reduction(rule) -> tuple:
    """(length, rule name, keep, tree name, single) of a reduce by `rule`, its value shaped as lark's tree builder
    shapes it (lark.parse_tree_builder, LALR, maybe_placeholders).

    `keep(children)` drops the anonymous tokens (`"{"`), puts None where a `[...]` was left out and takes in
    the children of `_rules` (keep None: all children kept as they are). The tree is named after the rule or its
    alias (`-> add`); the name is PASS for a `?rule: child`, and None for a `_rule`, whose value is the plain
    list of its children (lark builds a tree that the rule above takes apart). `single`: a `?rule`, which
    gives its only child, when it has one, instead of a tree.
    """
    length, origin = len(rule.expansion), rule.origin.name
    if _passes_through(rule):
        return length, origin, None, PASS, True
    name = None if origin.startswith("_") else rule.alias or origin
    single = bool(rule.options.expand1 and not rule.alias)
    nones = _placeholders(rule)
    plan = []  # (index, a `_rule` taken in?, Nones before it)
    for index, symbol in enumerate(rule.expansion):
        if rule.options.keep_all_tokens or not (symbol.is_term and symbol.filter_out):
            plan.append((index, not symbol.is_term and symbol.name.startswith("_"), nones[index]))
        else:
            nones[index + 1] += nones[index]
    trailing = nones[-1]
    if not trailing and plan == [(index, False, 0) for index in range(length)]:
        return length, origin, None, name, single

    def keep(children: list) -> list:
        kept = []
        for index, take, before in plan:
            if before:
                kept += [None] * before
            if take and not kept:
                kept = children[index]  # the list a `_rule` built, grown in place: `item*` is not quadratic
            elif take:
                kept += children[index]
            else:
                kept.append(children[index])
        if trailing:
            kept += [None] * trailing
        return kept

    return length, origin, keep, name, single


def _placeholders(rule) -> list:
    """How many Nones stand before each symbol of the rule, and after the last: the `[...]` left out."""
    empty = rule.options.empty_indices
    if not empty:
        return [0] * (len(rule.expansion) + 1)
    # empty_indices: a False per symbol written, a True per `[...]` left out, in order
    return [len(ones) for ones in "".join("1" if left_out else "0" for left_out in empty).split("0")]


def _passes_through(rule) -> bool:
    """`?sum: product`: the reduce returns its one child unchanged (two thirds of all reduces in a scene)."""
    (symbol,) = rule.expansion if len(rule.expansion) == 1 else (None,)
    return (rule.options.expand1 and not rule.alias and not rule.options.empty_indices and symbol is not None
            and not symbol.is_term and not symbol.name.startswith("_"))


def _scanner(lexer, blanks: str) -> tuple:
    """(match, keywords) of one state's lexer: its regex (then any blanks), the keywords a NAME may turn into."""
    scanner = lexer.scanner  # built on first use
    if len(scanner._mres) != 1:
        raise NotImplementedError("a lexer state with more than one regex (over 100 terminals)")
    keywords = None
    for kind, callback in lexer.callback.items():
        if kind != "NAME" or type(callback) is not UnlessCallback:
            raise NotImplementedError(f"a lexer callback on {kind}")
        # lark's UnlessCallback full-matches the NAME against the keyword strings: a dictionary does the same
        keywords = {terminal.pattern.value: terminal.name for terminal in callback.scanner.terminals
                    if terminal.pattern.type == "str" and not terminal.pattern.flags}
        if len(keywords) != len(callback.scanner.terminals):
            raise NotImplementedError("a keyword with flags")
    regex = scanner._mres[0]
    return re.compile(f"(?:{regex.pattern})(?:{blanks})?", regex.flags).match, keywords
