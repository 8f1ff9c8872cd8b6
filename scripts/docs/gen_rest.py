"""The REST page: every route and schema, from the OpenAPI document of ``backend.app.create_app()``.

Rendered as Markdown tables at build time (no Swagger UI, nothing fetched from a CDN); the
running service serves the same document at ``/openapi.json`` and an offline Swagger UI at
``/docs``.
"""

from __future__ import annotations

import json

from _md import fill, table

METHODS = ("get", "post", "put", "patch", "delete")


def openapi() -> dict:
    from backend.app import create_app

    return create_app().openapi()


def _anchor(name: str) -> str:
    return f"schema-{name.lower()}"


def _type(schema: dict) -> str:
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[1]
        return f"[{name}](#{_anchor(name)})"
    for key in ("anyOf", "oneOf", "allOf"):
        if key in schema:
            return " or ".join(_type(s) for s in schema[key])
    if "enum" in schema:
        return " or ".join(f"`{json.dumps(v)}`" for v in schema["enum"])
    if "const" in schema:
        return f"`{json.dumps(schema['const'])}`"
    t = schema.get("type", "any")
    if t == "array":
        return f"array of {_type(schema.get('items', {}))}"
    if t == "object" and isinstance(schema.get("additionalProperties"), dict):
        return f"object of {_type(schema['additionalProperties'])}"
    return t


def _default(schema: dict) -> str:
    return f"`{json.dumps(schema['default'])}`" if "default" in schema else ""


def _route_anchor(path: str, method: str) -> str:
    parts = (p.replace("{", "").replace("}", "").replace(".", "-") for p in path.split("/") if p)
    return "route-" + method + "-" + "-".join(parts)


def _first_sentence(op: dict) -> str:
    text = (op.get("description") or op.get("summary") or "").strip().split("\n\n", 1)[0]
    return text.split(". ", 1)[0].split("; ", 1)[0].replace("\n", " ").rstrip(".")


def _route(path: str, method: str, op: dict) -> list[str]:
    out = [f"### {method.upper()} `{path}` {{#{_route_anchor(path, method)}}}", ""]
    if op.get("summary"):
        out += [f"**{op['summary']}.** " + (op.get("description") or "").strip(), ""]
    params = op.get("parameters", [])
    if params:
        rows = [
            (
                f"`{p['name']}`",
                p["in"],
                _type(p.get("schema", {})),
                "yes" if p.get("required") else "",
                p.get("description", ""),
            )
            for p in params
        ]
        out += [table(("parameter", "in", "type", "required", "meaning"), rows)]
    body = op.get("requestBody")
    if body:
        types = [f"{_type(c.get('schema', {}))} (`{mt}`)" for mt, c in body.get("content", {}).items()]
        out += ["Request body: " + ", ".join(types) + ".", ""]
    rows = []
    for status, resp in op.get("responses", {}).items():
        content = resp.get("content", {})
        kinds = [
            f"{_type(c.get('schema', {}))} (`{mt}`)" if c.get("schema") else f"`{mt}`" for mt, c in content.items()
        ]
        rows.append((f"`{status}`", resp.get("description", ""), ", ".join(kinds)))
    out += [table(("status", "meaning", "body"), rows)]
    return out


def _schema(name: str, schema: dict) -> list[str]:
    out = [f"### {name} {{#{_anchor(name)}}}", ""]
    if schema.get("description"):
        out += [schema["description"].strip(), ""]
    props = schema.get("properties", {})
    required = set(schema.get("required", []))
    if props:
        rows = [
            (f"`{k}`", _type(v), "yes" if k in required else "", _default(v), v.get("description", ""))
            for k, v in props.items()
        ]
        out += [table(("field", "type", "required", "default", "meaning"), rows)]
    else:
        out += [f"Type: {_type(schema)}.", ""]
    return out


def pages() -> dict[str, str]:
    doc = openapi()
    routes, summary = [], []
    for path, item in doc["paths"].items():
        for method in METHODS:
            if method in item:
                op = item[method]
                routes += _route(path, method, op)
                link = f"[`{method.upper()} {path}`](#{_route_anchor(path, method)})"
                summary.append((link, _first_sentence(op)))
    schemas: list[str] = []
    for name, schema in sorted(doc.get("components", {}).get("schemas", {}).items()):
        schemas += _schema(name, schema)
    head = f"OpenAPI {doc.get('openapi', '')}, API version {doc['info'].get('version', '')}."
    parts = {
        "rest-summary": head + "\n\n" + table(("route", "what it does"), summary),
        "rest-routes": "\n".join(routes),
        "rest-schemas": "\n".join(schemas),
    }
    return {"rest.md": fill("rest.md", parts)}
