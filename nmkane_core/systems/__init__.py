"""The built-in systems, defined through the public API (nothing special-cased):
the paper's two examples, a catalogue of classic nonholonomic systems and the IFToMM
multibody benchmarks that today's compiled path runs (A01, A03, A05).
`nmkane_core.run.registry` registers `BUILTIN`.

A02 (`iftomm_a02.iftomm_a02`, the N-four-bar through its singular position) and A04
(`iftomm_a04`, Bricard's redundant closure) are declared and tested through the numpy
reference's rank-robust solve; they join `BUILTIN` when the compiled kernel has it
(docs/closed-loops.md)."""

from . import (
    appell_hamel,
    chaplygin_sleigh,
    iftomm_a01,
    iftomm_a03,
    iftomm_a05,
    knife_edge,
    odometer_puck,
    rolling_disk,
    sliding_particle,
    whipple_bicycle,
)

BUILTIN = {
    "appell-hamel": appell_hamel.appell_hamel,
    "sliding-particle": sliding_particle.sliding_particle,
    "knife-edge": knife_edge.knife_edge,
    "chaplygin-sleigh": chaplygin_sleigh.chaplygin_sleigh,
    "rolling-disk": rolling_disk.rolling_disk,
    "odometer-puck": odometer_puck.odometer_puck,
    "whipple-bicycle": whipple_bicycle.whipple_bicycle,
    "iftomm-a01": iftomm_a01.iftomm_a01,
    "iftomm-a03": iftomm_a03.iftomm_a03,
    "iftomm-a05": iftomm_a05.iftomm_a05,
}
