"""The built-in systems, defined through the public API (nothing special-cased):
the paper's two examples, a catalogue of classic nonholonomic systems and the IFToMM
multibody benchmarks A01–A05.  `nmkane_core.run.registry` registers `BUILTIN`.

A02 (`iftomm_a02`, the N-four-bar through its singular position) and A04 (`iftomm_a04`,
Bricard's redundant closure) run on the compiled kernel's rank-robust solve
(docs/closed-loops.md §7).  A02 is built in with N = 2 (`iftomm-a02`, the case OpenSim 3.2
times); the benchmark's own N = 40 is the system `iftomm_a02.iftomm_a02(40)`
(`iftomm-a02-n40`), loaded from examples/iftomm_a02_n40.py — its registration derives a model
of 81 coordinates (seconds), which a catalogue that every first use registers would pay."""

from . import (
    appell_hamel,
    chaplygin_sleigh,
    iftomm_a01,
    iftomm_a02,
    iftomm_a03,
    iftomm_a04,
    iftomm_a05,
    knife_edge,
    odometer_puck,
    rattleback,
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
    "rattleback": rattleback.rattleback,
    "whipple-bicycle": whipple_bicycle.whipple_bicycle,
    "iftomm-a01": iftomm_a01.iftomm_a01,
    "iftomm-a02": iftomm_a02.iftomm_a02,
    "iftomm-a03": iftomm_a03.iftomm_a03,
    "iftomm-a04": iftomm_a04.iftomm_a04,
    "iftomm-a05": iftomm_a05.iftomm_a05,
}
