"""The static check of generated code: the first filter, before any process is started.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from dataclasses import dataclass

from . import policy

MAX_CODE_CHARS = 100_000
_MAX_LISTED_PROBLEMS = 5

_ALLOWED_NODES: tuple[type[ast.AST], ...] = (
    # statements
    ast.Module, ast.Expr, ast.Assign, ast.AugAssign, ast.AnnAssign, ast.For, ast.While,
    ast.If, ast.Break, ast.Continue, ast.Pass, ast.FunctionDef, ast.ClassDef, ast.Return,
    ast.Delete, ast.Try, ast.TryStar, ast.ExceptHandler, ast.Raise, ast.Assert, ast.With,
    ast.withitem, ast.Import, ast.ImportFrom, ast.alias,
    # expressions
    ast.BoolOp, ast.BinOp, ast.UnaryOp, ast.IfExp, ast.Lambda, ast.Dict, ast.Set, ast.List,
    ast.Tuple, ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp, ast.comprehension,
    ast.Compare, ast.Call, ast.keyword, ast.FormattedValue, ast.JoinedStr, ast.Constant,
    ast.Attribute, ast.Subscript, ast.Starred, ast.Name, ast.Slice, ast.NamedExpr,
    ast.arguments, ast.arg,
    # operators and contexts
    ast.expr_context, ast.boolop, ast.operator, ast.unaryop, ast.cmpop,
)

_NODE_WORDS: dict[type[ast.AST], str] = {
    ast.Global: "the 'global' statement",
    ast.Nonlocal: "the 'nonlocal' statement",
    ast.Yield: "'yield' (generator functions)",
    ast.YieldFrom: "'yield from' (generator functions)",
    ast.AsyncFunctionDef: "'async def'",
    ast.AsyncFor: "'async for'",
    ast.AsyncWith: "'async with'",
    ast.Await: "'await'",
    ast.Match: "the 'match' statement",
    ast.TypeAlias: "a 'type' alias",
}


class CodeRejected(ValueError):
    """Generated code failed the static check. `line` is the 1-based line of the first
    problem (None if the code could not be parsed at all); `construct` names it."""

    def __init__(self, message: str, line: int | None = None, construct: str = ""):
        super().__init__(message)
        self.line = line
        self.construct = construct


@dataclass(frozen=True, order=True)
class _Problem:
    line: int
    column: int
    construct: str
    reason: str

    def text(self) -> str:
        return f"line {self.line}: {self.construct} is not allowed ({self.reason})"


def check_code(source: str) -> None:
    """Raise CodeRejected unless `source` passes the static allow-list check.

    The message names the line and the construct of the first problem, and lists a few more
    if there are several, so a language model can fix them all in one go.
    """
    if not isinstance(source, str):
        raise CodeRejected("the code must be a string", None, "non-string code")
    if len(source) > MAX_CODE_CHARS:
        raise CodeRejected(f"the code is longer than {MAX_CODE_CHARS} characters", None,
                           "oversized code")
    try:
        tree = ast.parse(source, filename="<generated code>", mode="exec")
    except SyntaxError as error:
        line = error.lineno
        where = f"line {line}: " if line else ""
        raise CodeRejected(f"syntax error: {where}{error.msg}", line, "syntax error") from None
    except (ValueError, RecursionError, MemoryError) as error:
        raise CodeRejected(f"the code could not be parsed: {error}", None,
                           "unparsable code") from None

    problems = sorted(_find_problems(tree))
    if not problems:
        return
    first = problems[0]
    shown = [problem.text() for problem in problems[:_MAX_LISTED_PROBLEMS]]
    more = len(problems) - len(shown)
    if more:
        shown.append(f"... and {more} more")
    message = "code rejected: " + "; ".join(shown)
    raise CodeRejected(message, first.line, first.construct)


def _find_problems(tree: ast.AST) -> list[_Problem]:
    """Every problem in the tree. The walk is iterative (deep nesting cannot overflow it),
    does not descend into a construct that is itself rejected, and gives nodes without a
    line of their own (operators, comprehensions, ...) the line of the node around them."""
    problems: list[_Problem] = []
    stack: list[tuple[ast.AST, int]] = [(tree, 1)]
    while stack:
        node, outer_line = stack.pop()
        line = getattr(node, "lineno", None) or outer_line
        column = getattr(node, "col_offset", None) or 0

        def add(construct: str, reason: str, line: int = line, column: int = column) -> None:
            problems.append(_Problem(line, column, construct, reason))

        if not isinstance(node, _ALLOWED_NODES):
            construct = _NODE_WORDS.get(type(node), f"the construct {type(node).__name__}")
            add(construct, "it is outside the small language generated code may use")
            continue
        _check_node(node, add)
        stack.extend((child, line) for child in ast.iter_child_nodes(node))
    return problems


_Add = Callable[[str, str], None]


def _check_node(node: ast.AST, add: _Add) -> None:
    """The problems of one node itself (its children are checked on their own)."""

    def check_name(name: str, role: str) -> None:
        reason = policy.name_problem(name)
        if reason:
            add(f"{role} {name!r}", reason)

    if isinstance(node, ast.Name):
        check_name(node.id, "the name")
    elif isinstance(node, ast.Attribute):
        reason = policy.attribute_problem(node.attr)
        if reason:
            add(f"the attribute {node.attr!r}", reason)
    elif isinstance(node, ast.FunctionDef):
        check_name(node.name, "the function name")
    elif isinstance(node, ast.ClassDef):
        check_name(node.name, "the class name")
        if node.keywords:
            add(f"the class keyword {node.keywords[0].arg!r}",
                "classes may not take keyword arguments such as metaclass=")
    elif isinstance(node, ast.arg):
        check_name(node.arg, "the parameter")
    elif isinstance(node, ast.keyword):
        if node.arg is not None and node.arg.startswith("_"):
            add(f"the keyword argument {node.arg!r}", policy.PRIVATE_REASON)
    elif isinstance(node, ast.ExceptHandler):
        if node.name is not None:
            check_name(node.name, "the exception variable")
    elif isinstance(node, ast.Import):
        for alias in node.names:
            if alias.name not in policy.ALLOWED_MODULES:
                add(f"import of module {alias.name!r}", _allowed_modules_text())
            if alias.asname is not None:
                check_name(alias.asname, "the import alias")
    elif isinstance(node, ast.ImportFrom):
        _check_import_from(node, add, check_name)


def _check_import_from(node: ast.ImportFrom, add: _Add,
                       check_name: Callable[[str, str], None]) -> None:
    module = node.module or ""
    if node.level:
        add(f"the relative import 'from {'.' * node.level}{module} import ...'",
            _allowed_modules_text())
        return
    if module not in policy.ALLOWED_MODULES:
        add(f"import from module {module!r}", _allowed_modules_text())
        return
    for alias in node.names:
        if alias.name == "*":
            add(f"'from {module} import *'", "import the names you need one by one")
            continue
        reason = policy.attribute_problem(alias.name)
        if reason:
            add(f"importing {alias.name!r} from {module!r}", reason)
        if alias.asname is not None:
            check_name(alias.asname, "the import alias")


def _allowed_modules_text() -> str:
    names = ", ".join(sorted(policy.ALLOWED_MODULES))
    return f"only these modules may be imported: {names}"
