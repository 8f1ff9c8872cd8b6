"""``nmkane serve`` refuses a port or host it cannot bind before anything starts (issue 44):
``--api-port 99999`` bound port 34463 (its value modulo 2¹⁶), ``--api-port -5`` and
``--host 999.1.1.1`` ended as "is the port in use?"."""

import pytest

from backend import serve as serve_module
from nmkane_core.cli import main


@pytest.fixture()
def no_serve(monkeypatch):
    def refuse(**kwargs):
        raise AssertionError("the service started with a bad address")

    monkeypatch.setattr(serve_module, "serve", refuse)


@pytest.mark.parametrize(
    "argv, option, value",
    [
        (["--api-port", "99999"], "--api-port", "99999"),
        (["--api-port", "-5"], "--api-port", "-5"),
        (["--viser-port", "65536"], "--viser-port", "65536"),
        (["--host", "999.1.1.1"], "--host", "'999.1.1.1'"),
        (["--host", "no-such-host.invalid"], "--host", "'no-such-host.invalid'"),
    ],
)
def test_a_bad_port_or_host_exits_2_with_one_line_naming_it(no_serve, capsys, argv, option, value):
    assert main(["serve", "--no-web", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f"{option}: got {value}" in err
    assert ("[0, 65535]" in err) if "port" in option else ("address" in err)


def test_good_addresses_reach_the_service(monkeypatch):
    seen = []
    monkeypatch.setattr(serve_module, "serve", lambda **kw: seen.append((kw["host"], kw["api_port"])))
    for host in ("127.0.0.1", "::1", "localhost"):
        assert main(["serve", "--no-web", "--host", host, "--api-port", "0"]) == 0
    assert seen == [("127.0.0.1", 0), ("::1", 0), ("localhost", 0)]
