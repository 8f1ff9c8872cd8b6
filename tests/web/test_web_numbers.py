"""Number boxes read what people type, exactly, or say why not (the teacher's item 1):
the parser, the log slider's units and marks, and a field's refusals beside the box."""

import math

import pytest
import viser

from web.numbers import NumberField, fmt, linear_marks, log_marks, parse_number


@pytest.mark.parametrize(
    "text,value",
    [
        ("1e-3", 0.001),
        ("-1e1", -10.0),
        ("2.5E+2", 250.0),
        ("0.001", 0.001),
        ("5e-1", 0.5),
        ("1e6", 1e6),
        (".5", 0.5),
        ("7.", 7.0),
        (" 3 ", 3.0),
        ("−10", -10.0),  # the minus sign the page itself writes
        ("+4", 4.0),
    ],
)
def test_what_people_type_is_read_exactly(text, value):
    assert parse_number(text) == value


@pytest.mark.parametrize(
    "text,why",
    [
        ("1,5", "decimal point as a point (1.5)"),
        ("abc", "is not a number"),
        ("", "empty"),
        ("1e", "is not a number"),
        ("nan", "is not a number"),
        ("inf", "is not a number"),
        ("1_000", "is not a number"),
        ("1e999", "too large"),
        ("2 kg", "is not a number"),
    ],
)
def test_anything_else_is_refused_with_the_reason(text, why):
    with pytest.raises(ValueError, match=why.replace("(", r"\(").replace(")", r"\)")):
        parse_number(text)


def test_values_are_shown_as_they_would_be_typed():
    shown = [fmt(v) for v in (0.001, 5.0, 2.5e-5, -10.0, 0.1 + 0.2, -0.0)]
    assert shown == ["0.001", "5", "2.5e-05", "-10", "0.3", "0"]


def test_log_sliders_are_marked_in_the_quantitys_own_units():
    assert log_marks(0.01, 100.0) == ((-2.0, "0.01"), (-1.0, "0.1"), (0.0, "1"), (1.0, "10"), (2.0, "100"))
    assert [lab for _, lab in log_marks(1e-4, 0.2)] == ["0.0001", "0.001", "0.01", "0.1"]
    assert [lab for _, lab in log_marks(0.05, 0.2)] == ["0.05", "0.2"]  # no decade inside: the ends
    assert [lab for _, lab in linear_marks(-50.0, 10.0)] == ["-50", "0", "10"]


@pytest.fixture(scope="module")
def gui():
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv.gui
    srv.stop()


def test_a_mass_on_a_log_slider_is_typed_in_kg_and_refused_outside_its_range(gui):
    seen, reports = [], []
    f = NumberField(gui, "M [kg]", 5.0, 0.05, 1e6, 0.04, log=True, unit="kg", report=lambda _f, t: reports.append(t))
    f.on_change(lambda: seen.append(f.value))
    assert f.text.value == "5" and f.slider.value == pytest.approx(math.log10(5.0))
    f.text.value = "2.5E+2"  # typed (set from Python: applied at once)
    assert seen == [250.0] and f.slider.value == pytest.approx(math.log10(250.0))
    f.text.value = "1e9"
    assert seen == [250.0] and f.value == 250.0 and f.message.visible
    assert "outside the allowed range 0.05 … 1000000 kg" in f.message.content and "keeps 250 kg" in f.message.content
    assert f.text.value == "1e9"  # left as typed
    f.text.value = "abc"
    assert "is not a number" in f.message.content and f.value == 250.0
    f.slider.value = math.log10(20.0)  # dragged: rounded to the field's significant digits
    assert seen[-1] == 20.0 and f.text.value == "20" and not f.message.visible
    assert reports[-1] is None and sum(r is not None for r in reports) == 2
