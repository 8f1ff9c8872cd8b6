"""``nmkane export``, the page's Export button and ``run.show()``: one self-contained HTML file
(viser's offline client with the recorded animation, and the plots as inline SVG), its frame
rule, and the errors that name the option (the browser test: test_export_browser.py)."""

import html
import re
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

import nmkane_core
from nmkane_core.cli import commands, main
from nmkane_core.errors import InputError, NmkaneError
from nmkane_core.run import viewer as core_viewer
from web import export
from web.app import MechanismApp

AH = "appell-hamel"
ROOT = Path(__file__).resolve().parents[2]
#: a reference that would make the page reach the network: src/href/url() to http(s) or //host
EXTERNAL = re.compile(
    r"""(?:\bsrc|\bhref|\baction)\s*=\s*["']?\s*(?:https?:)?//"""  # an attribute
    r"""|url\(\s*["']?\s*(?:https?:)?//""",  # a style
    re.I,
)


def _declared() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]


@pytest.fixture
def entry_points_declared(monkeypatch):
    """The entry points pyproject.toml declares, as importlib finds them: from the installed
    metadata, plus those an install older than this change lacks (``make setup`` installs again
    when pyproject.toml changes)."""
    real, declared = metadata.entry_points, _declared()

    def entry_points(group=None, **kw):
        found = list(real(group=group, **kw))
        names = {ep.name for ep in found}
        found += [metadata.EntryPoint(n, v, group) for n, v in declared.get(group, {}).items() if n not in names]
        return found

    monkeypatch.setattr(commands, "entry_points", entry_points)
    monkeypatch.setattr(core_viewer, "entry_points", entry_points)
    commands.all_commands.cache_clear()
    yield
    commands.all_commands.cache_clear()


@pytest.fixture(scope="module")
def run():
    return nmkane_core.simulate({"system": AH, "t_final": 2.0, "dt": 0.01}, progress=False)


@pytest.fixture(scope="module")
def page(run) -> str:
    return export.export_html(run)


def test_pyproject_declares_the_export_command_and_the_notebook_viewer():
    eps = _declared()
    assert eps["nmkane.commands"]["export"] == "web.cli:EXPORT"
    assert eps["nmkane.show"]["web"] == "web.export:show"


def test_frames_are_30_per_second_of_playback_and_at_most_1200():
    ten = export.frames(10.0)
    assert len(ten.times) == 301 and ten.step_s == pytest.approx(1 / 30) and ten.duration_s == pytest.approx(10)
    long = export.frames(300.0)
    assert len(long.times) == export.MAX_FRAMES and long.duration_s == pytest.approx(300)  # 4 frames/s then
    slow = export.frames(0.03, speed=0.02)  # a benchmark slowed down: 1.5 s of playback
    assert len(slow.times) == 46 and slow.duration_s == pytest.approx(1.5)
    assert len(export.frames(0.0).times) == 2 and export.frames(5, speed=float("nan")).speed == 1.0


def test_the_export_is_one_file_that_references_nothing_outside(page, run):
    assert "window.__VISER_EMBED_DATA__=" in page and 'id="nmk-panel"' in page
    assert not EXTERNAL.search(page), EXTERNAL.search(page)
    assert "<title>Appell–Hamel mechanism (Example 1) — nmkane</title>" in page
    assert len(page) < 2_000_000  # viser's client is 0.82 MB of it


def test_the_page_shows_energy_drift_and_violation_plots_and_the_summary(page, run):
    plots = re.findall(r'<div class="nmk-plot" data-plot="([^"]+)"', page)
    assert plots[:2] == ["Energy drift ΔE(t)", "log₁₀ |constraint violation|"]
    assert page.count("<svg") >= len(plots) >= 3
    for name in run.violation:  # each constraint in the legend and the summary
        assert f"max |φ| {name}" in page and f">{name}<" in page
    assert "kutta-merson · Δt = 0.01 s · t = 0 … 2 s" in page
    assert re.search(r"<div>Force arrows: 1 m = [0-9.e+]+ N</div>", page)  # the scale: in the panel, not the scene


def test_export_writes_the_whole_file_or_nothing(tmp_path, run):
    out = export.write(run, tmp_path / "run.html")
    assert out.read_text(encoding="utf-8").rstrip().endswith("</html>")
    assert [p.name for p in tmp_path.iterdir()] == ["run.html"]


@pytest.mark.parametrize(
    ("path", "reason"), [("run.png", "ending in .html"), ("no-such-folder/run.html", "existing folder")]
)
def test_a_bad_out_path_is_refused_naming_out(tmp_path, path, reason):
    with pytest.raises(InputError) as e:
        export.check_out(tmp_path / path if "/" in path else path)
    assert e.value.field == "out" and reason in e.value.allowed


def test_a_gif_without_chromium_says_what_to_install(tmp_path, run, monkeypatch):
    from web import export_gif

    monkeypatch.setattr(export_gif, "chromium_path", lambda: None)
    with pytest.raises(NmkaneError, match="apt-get install chromium"):
        export_gif.write_gif(run, tmp_path / "run.gif")
    assert list(tmp_path.iterdir()) == []


def test_cli_export_writes_the_page(tmp_path, capsys, entry_points_declared):
    out = tmp_path / "run.html"
    code = main(["export", AH, "--t-final", "1", "--dt", "0.01", "--no-progress", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    text = out.read_text(encoding="utf-8")
    assert "__VISER_EMBED_DATA__" in text and not EXTERNAL.search(text)
    said = capsys.readouterr().out
    assert said.startswith("ok: ") and f"-> {out} (" in said and " MB, written in " in said


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--out", "run.png"], "--out: got 'run.png' (unknown format); allowed: a file name ending in .html"),
        (["--out", "missing/run.html"], "--out: got 'missing/run.html' (no folder missing)"),
        (["--dt", "-1", "--out", "run.html"], "--dt: got -1.0"),
        (["--set", "nope=1", "--out", "run.html"], "--set nope"),
    ],
)
def test_cli_export_errors_name_the_option(tmp_path, monkeypatch, capsys, entry_points_declared, args, says):
    monkeypatch.chdir(tmp_path)
    assert main(["export", AH, "--no-progress", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nmkane export: error: ") and says in err, err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_cli_export_needs_out(capsys, entry_points_declared):
    with pytest.raises(SystemExit) as e:
        main(["export", AH])
    assert e.value.code == 2 and "--out" in capsys.readouterr().err


def test_show_is_an_iframe_whose_srcdoc_is_the_page(run):
    from IPython.display import HTML

    shown = export.show(run, height=480)
    assert isinstance(shown, HTML)
    tag = re.fullmatch(r'<div><iframe srcdoc="([^"]*)" width="100%" height="480" [^>]*></iframe></div>', shown.data)
    assert tag is not None  # srcdoc, no src: nothing is fetched
    doc = html.unescape(tag.group(1))
    assert "__VISER_EMBED_DATA__" in doc and 'id="nmk-panel"' in doc and not EXTERNAL.search(doc)


def test_show_in_a_notebook_displays_the_scene_alone(run, monkeypatch, capsys):
    """viser's banner and goodbye reach neither stdout nor, in Jupyter (where rich's console
    displays into the cell), the cell's output: the first export in a notebook showed both."""
    import IPython.display
    import rich

    console = rich.get_console()
    shown = []
    monkeypatch.setattr(IPython.display, "display", lambda *a, **k: shown.append(a))
    monkeypatch.setattr(console, "is_jupyter", True)  # as rich finds it in a notebook
    export.show(run, height=300)
    assert shown == [] and capsys.readouterr().out == ""
    assert console.is_jupyter  # the console is as it was


def test_run_show_and_core_show_find_the_web_viewer(run, entry_points_declared):
    from IPython.display import HTML

    assert isinstance(run.show(height=300), HTML)
    shown = nmkane_core.show(AH, {"t_final": 0.5})
    assert isinstance(shown, HTML) and "srcdoc=" in shown.data
    with pytest.raises(InputError, match="system"):
        nmkane_core.show(AH, {"system": "knife-edge"})


def test_show_without_a_viewer_says_what_to_install(run, monkeypatch):
    monkeypatch.setattr(core_viewer, "entry_points", lambda group: [])
    with pytest.raises(NmkaneError, match=r"pip install 'nmkane\[web\]'"):
        run.show()


def test_the_export_button_sends_the_shown_run_with_its_ghost(server, monkeypatch):
    sent = []
    monkeypatch.setattr(server, "send_file_download", lambda name, data, **kw: sent.append((name, data, kw)))
    app = MechanismApp(server, sync=True, scene=AH)
    try:
        app.control("t_final").value = 2.0
        app.control("option.compare").value = "linear"
        app.export.button.value = True  # a click
        assert len(sent) == 1
        name, data, kw = sent[0]
        assert re.fullmatch(r"appell-hamel-\d{8}-\d{6}\.html", name) and kw == {"save_immediately": True}
        text = data.decode("utf-8")
        assert "__VISER_EMBED_DATA__" in text and "orange, dashed: linear (ghost)" in text
        assert app.export.last == (name, len(data)) and not app.export.button.disabled
    finally:
        app.close()


def test_the_exported_labels_do_not_cover_each_other_seen_from_the_files_camera(run):
    """The file plays recorded frames: each frame's label corners were chosen for the file's
    camera (web.labels), as the live page chooses them for the browser's (issue 43, item 6)."""
    from tests.web._pages import covering, label_boxes
    from web.camera import Viewport
    from web.labels import seen_from

    _, view, _ = export.record(export.trajectory(run))
    vp = Viewport()
    look_at, position = view.camera_plan(vp).whole
    seen = seen_from(look_at, position, vp)
    boxes = label_boxes(view.label_points(), seen)  # at the last frame
    assert len(boxes) >= 4 and covering(boxes) is None, covering(boxes)
