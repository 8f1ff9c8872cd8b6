"""The catalogue: one page per registered system, its facts from ``GET /api/systems``.

What a system declares — title, description, parameters, coordinates, speeds, variants and
their constraints, default state and run settings, what to try, a stability sweep — is read
from the running code (the same document the REST API serves), so it cannot go stale and a
newly registered system gets its page by itself.  ``docs/catalogue/NAME.md``, where it
exists, adds the hand-written physics and references above the generated facts; a
hand-written page for a system that is not registered fails the build.  Screenshots
``docs/screenshots/NAME.png`` and ``NAME-*.png`` are shown where they exist.
"""

from __future__ import annotations

from functools import lru_cache

from _md import DOCS, code, fill, number, table


@lru_cache(maxsize=1)
def systems_document() -> dict:
    """The body of ``GET /api/systems``, asked of the app itself (no server, no store written)."""
    import tempfile
    import warnings

    with warnings.catch_warnings():  # starlette's TestClient on httpx: a deprecation notice, not ours
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient

    from backend.app import create_app
    from backend.config import Settings

    with tempfile.TemporaryDirectory() as tmp:
        app = create_app(Settings(data_dir=tmp, warm_kernels=False))
        with TestClient(app, base_url="http://localhost") as client:
            answer = client.get("/api/systems")
    answer.raise_for_status()
    return answer.json()


def _range(p: dict) -> str:
    low = "[" if p["min_inclusive"] else "("
    return f"{low}{number(p['min'])}, {number(p['max'])}]"


def _screenshots(name: str) -> list[str]:
    folder = DOCS / "screenshots"
    shots = sorted(folder.glob(f"{name}.png")) + sorted(folder.glob(f"{name}-*.png"))
    return [f"![{s.stem}](../screenshots/{s.name})" for s in shots]


def facts(s: dict) -> str:
    option = s["option"]
    variants = s[option + "s"]
    out = []
    if s.get("what_to_try"):
        out += ["## What to try", "", s["what_to_try"], ""]
    out += [
        "## Run it",
        "",
        "```console",
        f"$ nmkane run {s['name']}",
        f"$ nmkane matrices {s['name']} --matrix A1 --matrix T",
        f"$ nmkane serve --scene {s['name']}      # the 3D page opens on it",
        "```",
        "",
        "```python",
        "from nmkane_core import simulate",
        "",
        f'run = simulate({{"system": "{s["name"]}", "t_final": 1}})',
        "```",
        "",
    ]
    shots = _screenshots(s["name"])
    if shots:
        out += ["## Screenshots", "", *shots, ""]
    out += ["## Declared", "", "*Generated from the system's declaration when this site was built.*", ""]
    rows = [
        ("coordinates q", ", ".join(code(c) for c in s["coordinates"])),
        ("speeds u", ", ".join(code(c) for c in s["speeds"])),
        ("independent values (set by a user; the rest is completed)", ", ".join(code(c) for c in s["independent"])),
        ("default initial values", ", ".join(f"{k} = {number(v)}" for k, v in s["default_initial"].items())),
    ]
    out += [table(("", ""), rows)]
    vrows = [
        (
            code(v) + (" (default)" if v == s["default_" + option] else ""),
            ", ".join(code(c) for c in s["constraint_names"][v]) or "none",
        )
        for v in variants
    ]
    out += [f"### {option.capitalize()}s and their constraints", "", table((option, "constraints"), vrows)]
    frows = [
        (code(v), code(f["name"]), ", ".join(code(c) for c in f["components"]), f["route"], f["on"])
        for v in variants
        for f in s.get("forces", {}).get(v, [])
        if "error" not in f
    ]
    if frows:
        out += ["### Forces at points", "", "Reported by every run: see [Constraint forces](../forces.md).", ""]
        out += [table((option, "force", "components (N)", "route", "acts on"), frows)]
    prows = [(code(p["name"]), number(p["default"]), _range(p), p["unit"], p["description"]) for p in s["parameters"]]
    out += ["### Parameters", "", "Set with `--set NAME=VALUE` or `params` in the run settings.", ""]
    out += [table(("name", "default", "allowed", "unit", "meaning"), prows)]
    d = s["defaults"]
    out += [
        "### Run defaults",
        "",
        table(("setting", "default"), [(code(k), code(number(v))) for k, v in d.items()]),
    ]
    st = s.get("stability")
    if st:
        ref = ", ".join(f"{k} = {number(v)}" for k, v in st["reference"].items()) or "none"
        out += [
            "### Stability sweep",
            "",
            f"`nmkane stability {s['name']}` sweeps {st['over']} from {number(st['start'])} to "
            f"{number(st['stop'])} {st['unit']} ({st['count']} values), linearizing "
            f"{', '.join(code(k) for k in st['keep'])}; published crossings: {ref}.",
            "",
        ]
    return "\n".join(out)


def pages() -> dict[str, str]:
    doc = systems_document()
    systems = {s["name"]: s for s in doc["systems"]}
    written = {p.stem for p in (DOCS / "catalogue").glob("*.md")} - {"index"}
    unknown = written - set(systems)
    if unknown:
        raise RuntimeError(f"docs/catalogue/{sorted(unknown)[0]}.md names no registered system")
    out: dict[str, str] = {}
    rows, nav = [], ["* [Overview](index.md)"]
    for name, s in systems.items():
        page = f"catalogue/{name}.md"
        if name in written:
            out[page] = fill(page, {"facts": facts(s)})
        else:
            out[page] = f"# {s['title'] or name}\n\n`{name}` — {s['description']}\n\n{facts(s)}"
        option = s["option"]
        variants = s[option + "s"]
        constraints = ", ".join(s["constraint_names"][s["default_" + option]])
        if len(variants) > 1:
            constraints += (
                f" ({option} `{s['default_' + option]}`; also "
                + ", ".join(f"`{v}`" for v in variants if v != s["default_" + option])
                + ")"
            )
        rows.append((f"[{s['title'] or name}]({name}.md)<br>`{name}`", s["description"], constraints))
        nav.append(f"* [{s['title'] or name}]({name}.md)")
    listing = table(("system", "what it is", "constraints"), rows)
    out["catalogue/index.md"] = fill("catalogue/index.md", {"systems": listing})
    out["catalogue/SUMMARY.md"] = "\n".join(nav) + "\n"
    return out
