"""Generated code compiled so that every attribute it reads goes through `views`.

`compile_guarded(code, filename)` parses the code and rewrites `obj.name` (read) into
`__sandbox_attribute__(obj, "name")` and `obj.name <op>= value` into
`__sandbox_augmented__(obj, "name", "<Op>", value)`; both names are builtins of the
sandbox (`restricted.make_builtins`). Lines and columns are kept, so errors name the code's
own lines. Code that names either helper is refused (only possible with the static check
off: it forbids names starting with '_').

Standard library only.
"""

from __future__ import annotations

import ast
from types import CodeType

ATTRIBUTE_HELPER = "__sandbox_attribute__"
AUGMENTED_HELPER = "__sandbox_augmented__"
HELPERS = frozenset({ATTRIBUTE_HELPER, AUGMENTED_HELPER})


class _Guard(ast.NodeTransformer):
    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id in HELPERS:
            raise SyntaxError(f"the name {node.id!r} is reserved for the sandbox")
        return node

    def visit_Attribute(self, node: ast.Attribute) -> ast.AST:
        self.generic_visit(node)
        if not isinstance(node.ctx, ast.Load):
            return node
        call = ast.Call(func=ast.Name(ATTRIBUTE_HELPER, ast.Load()),
                        args=[node.value, ast.Constant(node.attr)], keywords=[])
        return ast.copy_location(call, node)

    def visit_AugAssign(self, node: ast.AugAssign) -> ast.AST:
        self.generic_visit(node)
        if not isinstance(node.target, ast.Attribute):
            return node
        call = ast.Call(func=ast.Name(AUGMENTED_HELPER, ast.Load()),
                        args=[node.target.value, ast.Constant(node.target.attr),
                              ast.Constant(type(node.op).__name__), node.value],
                        keywords=[])
        return ast.copy_location(ast.Expr(ast.copy_location(call, node)), node)


def compile_guarded(code: str, filename: str) -> CodeType:
    """The code, compiled with every attribute read guarded (see the module docstring)."""
    tree = _Guard().visit(ast.parse(code, filename, "exec"))
    return compile(ast.fix_missing_locations(tree), filename, "exec")
