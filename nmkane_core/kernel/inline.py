"""Source-level inlining of the generated kernels' marked calls (``# INLINE``).

numba's ``inline="always"`` does the same on its IR but deep-copies it for every call site
(seconds of compilation for the right-hand side), and a plain call costs ~20% of the loop's
time and keeps LLVM from forwarding the stores into the work array to their loads; so the
generator expands the marked calls in the text before numba sees it.
"""

from __future__ import annotations

import ast
import copy

__all__ = ["inline_marked"]


class _Rename(ast.NodeTransformer):
    """Rename variables (``str`` values) or substitute expressions (AST values)."""

    def __init__(self, mapping: dict):
        self.mapping = mapping

    def visit_Name(self, node):
        new = self.mapping.get(node.id)
        if new is None:
            return node
        if isinstance(new, str):
            return ast.copy_location(ast.Name(id=new, ctx=node.ctx), node)
        return ast.copy_location(copy.deepcopy(new), node)


def _inline_body(fn: ast.FunctionDef, args: list, target, tag: str) -> list:
    """The statements of ``fn`` for one call: parameters bound to ``args``, locals renamed
    apart with ``tag``, a final ``return e`` turned into ``target = e`` (dropped if no target)."""
    body = list(fn.body)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]  # the docstring
    returns = [n for st in body for n in ast.walk(st) if isinstance(n, ast.Return)]
    if returns and (len(returns) > 1 or body[-1] is not returns[0]):
        raise RuntimeError(f"{fn.name}: only a function whose one return ends it can be inlined")
    params = [a.arg for a in fn.args.args]
    if len(args) != len(params):
        raise RuntimeError(f"{fn.name}: called with {len(args)} arguments, takes {len(params)}")
    stores = {n.id for st in body for n in ast.walk(st) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
    mapping, out = {}, []
    for name, arg in zip(params, args, strict=True):
        if name not in stores and isinstance(arg, (ast.Name, ast.Constant)):
            mapping[name] = arg.id if isinstance(arg, ast.Name) else arg  # substitute
        else:
            mapping[name] = tag + name  # bind once
            out.append(ast.Assign(targets=[ast.Name(id=tag + name, ctx=ast.Store())], value=arg))
    for name in stores - set(params):
        mapping[name] = tag + name
    out += [_Rename(mapping).visit(copy.deepcopy(st)) for st in body]
    if returns:
        value = out.pop().value
        if target is not None:
            out.append(ast.Assign(targets=[target], value=value))
    return out


def inline_marked(source: str, keep_calls=()) -> str:
    """Inline at source level every call marked ``# INLINE`` in the module ``source``.

    A marked statement is ``f(args)  # INLINE`` or ``target = f(args)  # INLINE`` with ``f``
    a function of the module whose only ``return`` (if any) ends it.  The call becomes
    ``f``'s body, parameters bound and locals renamed apart; marked calls inside ``f`` are
    expanded first.  numba's ``inline="always"`` does the same on its IR but deep-copies it
    for every call site (seconds of compilation for the right-hand side), and a plain call
    costs ~20% of the loop's time and keeps LLVM from forwarding the stores into the work
    array to their loads.  Functions without marked calls keep their text and comments.
    Calls of the functions named in ``keep_calls`` stay calls even when marked.
    """
    lines = source.splitlines()
    tree = ast.parse(source)
    funcs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    expanded: dict = {}
    changed: dict[str, bool] = {}
    count = [0]

    def marked(fn: ast.FunctionDef) -> bool:
        return any("# INLINE" in line for line in lines[fn.lineno - 1 : fn.end_lineno or fn.lineno])

    def expand(fn: ast.FunctionDef) -> ast.FunctionDef:
        if fn.name not in expanded and not marked(fn):  # nothing to expand: no copy (large generated bodies)
            changed[fn.name], expanded[fn.name] = False, fn
        if fn.name not in expanded:

            class Expander(ast.NodeTransformer):
                def _inline(self, st, call, target):
                    if not (
                        "# INLINE" in lines[st.lineno - 1]
                        and isinstance(call, ast.Call)
                        and isinstance(call.func, ast.Name)
                        and call.func.id in funcs
                        and call.func.id not in keep_calls
                    ):
                        return st
                    count[0] += 1
                    callee = expand(funcs[call.func.id])
                    return _inline_body(callee, call.args, target, f"_{callee.name}{count[0]}_")

                def visit_Expr(self, st):
                    return self._inline(st, st.value, None)

                def visit_Assign(self, st):
                    return self._inline(st, st.value, st.targets[0]) if len(st.targets) == 1 else st

            new = Expander().visit(copy.deepcopy(fn))  # line numbers kept: markers
            changed[fn.name] = ast.dump(new) != ast.dump(fn)
            expanded[fn.name] = new
        return expanded[fn.name]

    out, pos = [], 0
    for fn in funcs.values():
        new = expand(fn)
        if not changed[fn.name]:
            continue
        first = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
        out += lines[pos : first - 1]
        out.append(ast.unparse(ast.fix_missing_locations(new)))
        pos = fn.end_lineno or fn.lineno
    return "\n".join(out + lines[pos:]) + "\n"
