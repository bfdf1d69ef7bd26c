"""Machine files: the shipped ones load; [axes], [kinematics] and [gcode] refuse bad values with one
clear line naming the file and key."""
import math
import pathlib

import pytest

from meshmill.machine.config import load_machine, shipped_machines

SHIPPED = pathlib.Path(__file__).resolve().parents[1] / "src" / "meshmill" / "data" / "machines"
MOTION = (SHIPPED / "seed-002.toml").read_text()  # name and [motion] only
FIVE = MOTION + """[kinematics]
type = "table-table"
rotary = ["A", "C"]
[axes]
A = [-120, 30]
C = "continuous"
"""


def test_shipped_machines():
    names = shipped_machines()
    for want in ("generic-3axis", "linuxcnc-3axis", "grbl-3axis", "table-table-ac", "head-table-bc", "seed-002"):
        assert want in names
    ac = load_machine("table-table-ac")
    assert ac.axes == ("X", "Y", "Z", "A", "C") and ac.chain.type == "table-table" and "C" not in ac.limits
    assert ac.limits["A"] == (-120.0, 30.0) and ac.rotary_rapid == pytest.approx(150.0)
    bc = load_machine("head-table-bc")
    assert bc.axes == ("X", "Y", "Z", "B", "C") and bc.chain.head_length == 150.0 and bc.limits["C"] == (-360.0, 360.0)
    assert load_machine("grbl-3axis").gcode.comment == "; {text}" and not load_machine("grbl-3axis").gcode.inverse_time
    assert load_machine("linuxcnc-3axis").gcode.end[-2] == "M2"
    assert load_machine("generic-3axis").gcode.start[0] == "%"


def test_gcode_overrides_and_chain_details(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(FIVE.replace('rotary = ["A", "C"]', 'rotary = ["A", "C"]\nreversed = ["C"]\npivot_mm = [1, 2, 3]\nsingular_deg = 0.5')
                 + '[gcode]\ndialect = "linuxcnc"\ndecimals = 3\ntcp = "G43.4 H{number}"\nstart = ["%", "G21"]\n')
    m = load_machine(p)
    assert m.chain.reversed == ("C",) and m.chain.pivot == (1.0, 2.0, 3.0)
    assert m.chain.singular == pytest.approx(math.radians(0.5))
    assert m.gcode.dialect == "linuxcnc" and m.gcode.decimals == 3 and m.gcode.start == ("%", "G21")
    assert m.gcode.tcp == "G43.4 H{number}" and m.gcode.end[-2] == "M2"  # the dialect's end block stays
