"""The built-in systems, defined through the public API (nothing special-cased):
the paper's two examples and a catalogue of classic nonholonomic systems.
`nmkane_core.run.registry` registers `BUILTIN`."""

from . import appell_hamel, chaplygin_sleigh, knife_edge, odometer_puck, rolling_disk, sliding_particle, whipple_bicycle

BUILTIN = {
    "appell-hamel": appell_hamel.appell_hamel,
    "sliding-particle": sliding_particle.sliding_particle,
    "knife-edge": knife_edge.knife_edge,
    "chaplygin-sleigh": chaplygin_sleigh.chaplygin_sleigh,
    "rolling-disk": rolling_disk.rolling_disk,
    "odometer-puck": odometer_puck.odometer_puck,
    "whipple-bicycle": whipple_bicycle.whipple_bicycle,
}
