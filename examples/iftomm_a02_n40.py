"""IFToMM benchmark A02 at the benchmark's own size: the N-four-bar with N = 40 windows
(81 rods, 80 loop-closure equations) — an nmkane systems file.

The catalogue's ``iftomm-a02`` is the same mechanism with N = 2 (the case OpenSim 3.2 times:
10 s in 0.455 s of CPU); N is a structural choice (it changes the coordinates), so each N is
its own system, ``iftomm_a02.iftomm_a02(N)``, named ``iftomm-a02-n{N}``.  N = 40 is kept out of
the built-in catalogue because registering it derives a model of its own (the derivation and the
chain's model functions through the C compiler: about 5 s to the end of a first 20 s run from an
empty cache on two cores; the run itself, at its default Δt = 0.01, 0.6 s, with B0 within 2e-6 m
of the exact motion where the benchmark allows 1e-3):

    nmkane run iftomm-a02-n40 --systems examples/iftomm_a02_n40.py

(docs/catalogue/iftomm-a02.md gives the measured times).  The benchmark runs 20 s:
add ``--t-final 20``.
"""

from nmkane_core import register
from nmkane_core.systems import iftomm_a02

register(iftomm_a02.iftomm_a02(40))
