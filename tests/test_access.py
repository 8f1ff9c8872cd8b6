"""The one Host allow-list rule and token comparison (``nmkane_core.access``) that the REST
service and the web app's server both hold requests to."""

import subprocess
import sys
from pathlib import Path

import pytest

from nmkane_core.access import (
    LOOPBACK_NAMES,
    HostAllowList,
    allowed_host_names,
    host_name,
    is_ip,
    is_loopback,
    new_token,
    token_matches,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "header, name",
    [
        ("Lab.Example:8000", "lab.example"),
        ("lab.example", "lab.example"),
        ("[::1]:8000", "::1"),
        ("[::1]", "::1"),
        ("::1", "::1"),
        ("127.0.0.1:80", "127.0.0.1"),
        ("  LOCALHOST ", "localhost"),
        ("", ""),
    ],
)
def test_host_name_drops_the_port_and_the_brackets(header, name):
    assert host_name(header) == name


def test_the_allow_list_admits_its_names_and_any_ip_address_and_nothing_else():
    rule = HostAllowList.of("lab.example", ["Class.Example:8080"])
    for host in (
        "localhost:8000",
        "127.0.0.1",
        "[::1]:8000",
        "lab.example:1",
        "class.example",
        "10.1.2.3:8000",
        "[fe80::1]",
    ):
        assert rule.admits(host), host
    for host in ("evil.example", "localhost.evil.example:8000", "", "lab.example.evil.example", "[evil]"):
        assert not rule.admits(host), host


def test_allowed_names_skip_a_wildcard_bind_and_blank_extras():
    assert allowed_host_names("0.0.0.0", ["", " "]) == LOOPBACK_NAMES
    assert allowed_host_names("::", ()) == LOOPBACK_NAMES
    assert allowed_host_names("[::1]", ["LAB.example:8000", "lab.example"]) == (*LOOPBACK_NAMES, "lab.example")


def test_loopback_and_ip_tests():
    assert is_loopback("127.0.0.2") and is_loopback("[::1]") and is_loopback("app.localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5") and not is_loopback("lab.example")
    assert is_ip("10.0.0.1") and is_ip("fe80::1") and not is_ip("lab.example") and not is_ip("")


def test_tokens_are_long_random_and_compared_exactly():
    a, b = new_token(), new_token()
    assert a != b and len(a) >= 32
    assert token_matches(a, a) and not token_matches(b, a)
    assert not token_matches(None, a) and not token_matches("", a) and not token_matches(a[:-1], a)
    assert not token_matches("\udcff" + a, a)  # text no encoder accepts does not crash the check


def test_importing_access_loads_no_web_framework():
    code = (
        "import sys, nmkane_core.access\n"
        "heavy = {'fastapi', 'starlette', 'uvicorn', 'viser', 'websockets', 'backend', 'web'}\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]", out.stdout
