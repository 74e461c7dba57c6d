"""Machine file loading and validation."""
import pytest

from plcpred.machine import MachineError, check_against_program, load_machine
from plcpred.parser import parse_st

PROGRAM = """PROGRAM Station
VAR_INPUT start : BOOL; clamp_home, clamp_work : BOOL; END_VAR
VAR_OUTPUT clamp_valve, blow, lamp : BOOL; END_VAR
IF start AND clamp_home THEN clamp_valve := TRUE; END_IF
blow := clamp_valve;
lamp := FALSE;
END_PROGRAM
"""

GOOD = """
[machine]
name = "station"
program = "station.st"
scan_ms = 5
supply_bar_g = 6.0

[signals]
"%IX0.0" = "start"

[[input]]
signal = "%IX0.0"
period_s = 2.5
offset_s = 0.1
pulse_ms = 100

[[consumer]]
name = "clamp"
kind = "double_acting"
bore_mm = 32
rod_mm = 12
stroke_mm = 25
tube_id_mm = 4
tube_length_m = [0.5, 0.7]
valve = "clamp_valve"
stroke_time_s = [0.2, 0.25]
switch_delay_s = 0.015
switches = { retracted = "clamp_home", extended = "clamp_work" }

[[consumer]]
name = "blow-off"
kind = "nozzle"
valve = "blow"
orifice_mm = 1.5
Cd = 0.8

[[consumer]]
name = "leak"
kind = "leak"
C = 3.4e-10
b = 0.12
m = 0.9
"""


ONE_OUTPUT = "PROGRAM P VAR_OUTPUT y : BOOL; END_VAR END_PROGRAM"


def write(tmp_path, text, program=PROGRAM):
    (tmp_path / "station.st").write_text(program)
    f = tmp_path / "station.toml"
    f.write_text(text)
    return f


def test_good_file_loads_with_defaults(tmp_path):
    m = load_machine(write(tmp_path, GOOD))
    assert m.name == "station" and m.scan_ms == 5 and m.supply_bar_g == 6.0
    assert m.atmosphere_kpa == 101.325 and m.ambient_c == 20.0
    clamp = m.consumer("clamp")
    assert clamp.tube_length_m == (0.5, 0.7) and clamp.stroke_time_s == (0.2, 0.25)
    assert clamp.valve == ["clamp_valve"] and not clamp.bistable
    assert clamp.initial == "retracted"
    nozzle = m.consumer("blow-off")
    assert nozzle.b == 0.528 and nozzle.m == 0.5 and nozzle.flow_model == "iso6358"
    assert m.consumer("leak").valve == []
    assert m.inputs[0].period_s == 2.5 and m.inputs[0].pulse_ms == 100


def test_cross_check_with_program_warns_on_undriven_outputs_and_unread_switches(tmp_path):
    m = load_machine(write(tmp_path, GOOD))
    warnings = check_against_program(m, parse_st(PROGRAM))
    assert any("output 'lamp'" in w and "drives no consumer" in w for w in warnings)
    assert any("switch 'clamp_work' is never read" in w for w in warnings)
    assert not any("clamp_home" in w for w in warnings)


def test_unknown_signal_is_an_error_naming_table_and_key(tmp_path):
    m = load_machine(write(tmp_path, GOOD.replace('valve = "blow"', 'valve = "blower"')))
    with pytest.raises(MachineError) as ei:
        check_against_program(m, parse_st(PROGRAM))
    assert str(ei.value) == (f"{tmp_path / 'station.toml'}:33: consumer \"blow-off\": valve "
                             "'blower' is not a variable of station.st; did you mean 'blow'?")


@pytest.mark.parametrize("edit, message", [
    (("stroke_mm = 25", "stroke_mm = -25"), 'consumer "clamp": stroke_mm must be > 0'),
    (("stroke_mm = 25", "stroke_mm = 25\ncolour = 'red'"), 'consumer "clamp": unknown key \'colour\''),
    (("bore_mm = 32", "bor_mm = 32"), "unknown key 'bor_mm'; did you mean 'bore_mm'?"),
    (("[[input]]", "[[inputs]]"), "unknown table 'inputs'; did you mean 'input'?"),
    (("rod_mm = 12", "rod_mm = 40"), 'consumer "clamp": rod_mm (40) must be smaller than bore_mm'),
    (("bore_mm = 32\n", ""), "consumer \"clamp\": missing required key 'bore_mm'"),
    (('kind = "nozzle"', 'kind = "fan"'), 'kind must be one of'),
    (("orifice_mm = 1.5\nCd = 0.8", "orifice_mm = 1.5"), "orifice_mm needs a discharge coefficient Cd"),
    (('kind = "leak"', 'kind = "leak"\nvalve = "blow"'), 'consumer "leak": a leak is always on'),
    (("supply_bar_g = 6.0", ""), "[machine]: missing required key 'supply_bar_g'"),
    (('program = "station.st"', 'program = "missing.st"'), "program file 'missing.st' not found"),
    (("period_s = 2.5", "period_s = 0.05"), "pulse_ms must be shorter than period_s"),
    (('name = "blow-off"', 'name = "clamp"'), 'consumer "clamp": name is used twice'),
    (("[[input]]", "[input]"), "[[input]]: write it as [[input]]"),
    (("scan_ms = 5", "scan_ms = 'fast'"), "scan_ms must be a number"),
    (("switch_delay_s = 0.015", "switch_delay_s = 0.015\npartial_strokes = 1"),
     'consumer "clamp": partial_strokes must be true or false'),
    (("stroke_time_s = [0.2, 0.25]", "partial_strokes = true"),
     'consumer "clamp": partial_strokes needs stroke_time_s'),
    (("Cd = 0.8", "Cd = 0.8\npartial_strokes = true"),
     "'partial_strokes' applies to cylinders, not to a nozzle"),
])
def test_bad_files_name_table_and_key(tmp_path, edit, message):
    f = write(tmp_path, GOOD.replace(*edit, 1))
    with pytest.raises(MachineError) as ei:
        load_machine(f)
    assert message in str(ei.value)
    assert str(ei.value).startswith(str(f))


def test_bistable_valve_and_auto_stroke_time(tmp_path):
    text = GOOD.replace('valve = "clamp_valve"', 'valve = ["clamp_valve", "lamp"]').replace(
        "stroke_time_s = [0.2, 0.25]", 'stroke_time_s = "auto"')
    c = load_machine(write(tmp_path, text)).consumer("clamp")
    assert c.bistable and c.stroke_time_s == "auto"


def test_not_toml_is_a_clear_error(tmp_path):
    f = write(tmp_path, "[machine\nname=")
    with pytest.raises(MachineError, match="not valid TOML"):
        load_machine(f)


def test_auto_stroke_time_comes_from_the_plant(tmp_path):
    base = '''[machine]
program = "station.st"
supply_bar_g = {p}
[[consumer]]
name = "c"
kind = "double_acting"
bore_mm = 20
rod_mm = 8
stroke_mm = 150
tube_id_mm = 4
tube_length_m = 1.0
valve = "y"
stroke_time_s = "auto"
{extra}
'''

    def times(p=6, extra=""):
        text = base.format(p=p, extra=extra)
        return load_machine(write(tmp_path, text, ONE_OUTPUT)).consumer("c").stroke_times()

    ext, ret = times()
    assert 0.01 < ext < 1.0 and 0.01 < ret < 1.0
    # lifting 8 kg straight up slows the extend; lowering it is quicker than lifting
    ext_up, ret_up = times(extra="payload_kg = 8\nmount_angle_deg = 90")
    assert ext_up > 1.2 * ext and ret_up < ext_up
    # a lower supply pressure is slower
    assert times(p=3)[0] > ext
    # a load the pressure cannot lift is an error naming the drive
    with pytest.raises(MachineError, match='consumer "c".*does not extend'):
        times(p=1, extra="payload_kg = 50\nmount_angle_deg = 90")


def test_single_acting_cylinder_needs_no_rod(tmp_path):
    """It fills only its cap end (D1), so a rod diameter is not asked for; D1 gives the
    same air with or without one."""
    text = '''[machine]
program = "station.st"
supply_bar_g = 6
[[consumer]]
name = "c"
kind = "single_acting"
bore_mm = 32
stroke_mm = 50
valve = "y"
stroke_time_s = 0.2
'''
    c = load_machine(write(tmp_path, text, ONE_OUTPUT)).consumer("c")
    assert c.rod_mm == 0.0
    from plcpred.physics.volumes import consumer_stroke_volumes_nl
    no_rod = consumer_stroke_volumes_nl(c, 7.01325e5)
    with_rod = consumer_stroke_volumes_nl(
        load_machine(write(tmp_path, text + "rod_mm = 12\n", ONE_OUTPUT)).consumer("c"),
        7.01325e5)
    assert no_rod == with_rod and no_rod[1] == 0.0


def test_the_docs_key_tables_are_the_schemas():
    """docs/reference/machine-file.md's key tables are made from machine.schema
    (``python -m plcpred.machine.schema`` writes them): one place says what a key is."""
    from pathlib import Path

    from plcpred.machine import schema
    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference"
           / "machine-file.md").read_text()
    assert schema.with_tables(doc) == doc
    changed = schema.with_tables(doc.replace("| `bore_mm` | required |", "| `bore_mm` | 7 |"))
    assert changed == doc


def test_the_reader_reads_every_key_of_the_schema_and_no_other():
    """Every key the loader reads by name (r.number("bore_mm"), table.get("valve"), ...) is
    in the schema of some table, and every schema key is read: the two cannot drift."""
    import ast
    from pathlib import Path

    from plcpred.machine import load, schema
    tree = ast.parse(Path(load.__file__).read_text())
    read = set()
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("number", "pair", "string", "flag", "get", "_checked")
                and node.args and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)):
            read.add(node.args[0].value)
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Constant) and any(
                isinstance(op, ast.In) for op in node.ops):
            read.add(node.left.value)
        if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) \
                and isinstance(node.slice.value, str):
            read.add(node.slice.value)
    every = set().union(*(schema.keys(t) for t in schema.TABLES))
    unread = every - read - set(schema.PLANT_DRIVE_KEYS)
    assert not unread, f"schema keys the loader never reads: {sorted(unread)}"
    tables = {"machine", "input", "consumer", "line", "meter", "calendar", "live", "signals",
              "retracted", "extended"}
    names = {k for k in read if k.isidentifier() and k not in tables}
    unknown = {k for k in names - every if k.islower() or k in ("C", "Cd")}
    assert not unknown, f"keys read that the schema does not declare: {sorted(unknown)}"


def test_init_writes_only_keys_the_schema_declares(tmp_path):
    """The commented blocks of ``plcpred init`` use keys of their tables."""
    import re

    from plcpred.machine import schema
    from plcpred.parser import parse_st
    from plcpred.skeleton import machine_skeleton
    program = parse_st("PROGRAM P VAR xIn AT %IX0.0 : BOOL; qOut AT %QX0.0 : BOOL; "
                       "END_VAR qOut := xIn; END_PROGRAM", "p.st")
    text = machine_skeleton(program, tmp_path / "p.st", tmp_path / "m.toml")
    table = None
    for line in text.splitlines():
        body = line.lstrip("# ").strip()
        head = re.fullmatch(r"\[\[?(\w+)\]?\]", body)
        if head:
            table = head.group(1)
            continue
        key = re.match(r"(\w+) = ", body)
        if key and table:
            assert key.group(1) in schema.keys(table), (table, key.group(1))


def _one_knife(tmp_path, supply_bar_g, extra: str = ""):
    """A machine of one air knife on output y at ``supply_bar_g``."""
    return load_machine(write(tmp_path, f'''[machine]
program = "station.st"
supply_bar_g = {supply_bar_g}
[[consumer]]
name = "knife"
kind = "nozzle"
valve = "y"
orifice_mm = 1
Cd = 0.7
{extra}''', ONE_OUTPUT))


def test_a_nozzle_regulated_above_the_supply_is_warned_about(tmp_path):
    m = _one_knife(tmp_path, 4, "pressure_bar_g = 5\n")
    assert any('"knife"' in w and "cannot raise its supply" in w for w in m.warnings)


@pytest.mark.parametrize("supply, warned", [(87, True), (16, False), (6, False)])
def test_a_supply_in_psi_is_warned_about(tmp_path, supply, warned):
    m = _one_knife(tmp_path, supply)
    found = [w for w in m.warnings if "psi" in w]
    assert bool(found) == warned
    if warned:
        assert "6.00 bar(g)" in found[0] and "[machine]" in found[0]


def test_an_input_read_but_never_driven_is_warned_about(tmp_path):
    """The E-stop a machine file forgot to schedule keeps the station still: say so."""
    warnings = _lint_machine(tmp_path, """PROGRAM P
VAR_INPUT xEStopOk : BOOL; xStart : BOOL; END_VAR
VAR_OUTPUT y : BOOL; END_VAR
y := xEStopOk AND xStart;
END_PROGRAM""", '''[[input]]
signal = "xStart"
pulses_s = [1.0]
[[consumer]]
name = "c"
kind = "double_acting"
bore_mm = 20
rod_mm = 8
stroke_mm = 50
valve = "y"
''')
    hits = [w for w in warnings if "nothing drives it" in w]
    assert len(hits) == 1 and "'xEStopOk'" in hits[0]


def _lint_machine(tmp_path, program, body):
    """The warnings of a 3 s run of ``program`` with these tables."""
    from plcpred import unfold
    m = load_machine(write(tmp_path, '[machine]\nprogram = "station.st"\nsupply_bar_g = 6\n'
                                     + body, program))
    unfold(m, "3s")
    return m.warnings


def test_lint_nothing_moved_both_coils_and_a_valve_on_an_input(tmp_path):
    cyl = ('[[consumer]]\nname = "c"\nkind = "double_acting"\nbore_mm = 20\nrod_mm = 8\n'
           'stroke_mm = 50\nvalve = {valve}\n')
    # the E-stop deadlock: nothing ever moves
    w = _lint_machine(tmp_path, """PROGRAM P VAR_INPUT ok : BOOL; END_VAR
VAR_OUTPUT y : BOOL; END_VAR y := ok; END_PROGRAM""", cyl.format(valve='"y"'))
    assert any("nothing moved" in x for x in w)
    # a bistable valve with both coils on at 1 s
    w = _lint_machine(tmp_path, """PROGRAM P VAR_OUTPUT a, b : BOOL; END_VAR
VAR t : TON; END_VAR t(IN := TRUE, PT := T#1S); a := TRUE; b := t.Q; END_PROGRAM""",
                      cyl.format(valve='["a", "b"]'))
    hits = [x for x in w if "both solenoids" in x]
    assert len(hits) == 1 and "at 1 s" in hits[0]
    assert not any("nothing moved" in x for x in w)
    # a valve wired to an input
    w = _lint_machine(tmp_path, """PROGRAM P VAR_INPUT x : BOOL; END_VAR
VAR_OUTPUT y : BOOL; END_VAR y := x; END_PROGRAM""", cyl.format(valve='"x"'))
    assert any("valve 'x' is an input" in x for x in w)


def test_lint_a_first_scan_command_is_movement(tmp_path):
    w = _lint_machine(tmp_path, """PROGRAM P VAR_OUTPUT y : BOOL; END_VAR y := TRUE;
END_PROGRAM""", '[[consumer]]\nname = "c"\nkind = "double_acting"\nbore_mm = 20\n'
                'rod_mm = 8\nstroke_mm = 50\nvalve = "y"\n')
    assert not any("nothing moved" in x for x in w)


# ------------------------------------------------- errors and warnings at their line

def _line(text: str, needle: str, nth: int = 1) -> int:
    """The line of the ``nth`` line of ``text`` that holds ``needle``."""
    return [i for i, ln in enumerate(text.split("\n"), 1) if needle in ln][nth - 1]


@pytest.mark.parametrize("edit, at", [
    (("bore_mm = 32", "bor_mm = 32"), "bor_mm"),                   # unknown key
    (("stroke_mm = 25", "stroke_mm = 'long'"), "stroke_mm"),        # wrong type
    (("scan_ms = 5", "scan_ms = 1e9"), "scan_ms"),                  # outside its range
    (("rod_mm = 12", "rod_mm = 40"), "rod_mm"),                     # against another key
    (('kind = "nozzle"', 'kind = "nozle"'), "nozle"),               # a choice mistyped
    (('period_s = 2.5', 'period_s = 0.05'), "pulse_ms"),            # in [[input]]
    (("bore_mm = 32\n", ""), '[[consumer]]'),                       # missing: the table
    (('[[input]]', '[[inputs]]'), "[[inputs]]"),                    # unknown table
    (('name = "blow-off"', 'name = "clamp"'), ('name = "clamp"', 2)),  # the second one
])
def test_a_semantic_error_names_its_line_table_and_key(tmp_path, edit, at):
    text = GOOD.replace(*edit, 1)
    line = _line(text, *at) if isinstance(at, tuple) else _line(text, at)
    f = write(tmp_path, text)
    with pytest.raises(MachineError) as ei:
        load_machine(f)
    assert str(ei.value).startswith(f"{f}:{line}: "), (str(ei.value), line)


def test_the_line_is_found_past_multi_line_values_and_comments(tmp_path):
    text = GOOD.replace("tube_length_m = [0.5, 0.7]",
                        'tube_length_m = [\n  0.5,  # [[consumer]]\n  0.7,\n]\n'
                        'initial = """\nbore_mm = 1\n"""').replace("bore_mm = 32",
                                                                  "# bore_mm = 1\nbore_mm = 32")
    text = text.replace("switch_delay_s = 0.015", "switch_delay_s = 'x'")
    f = write(tmp_path, text)
    with pytest.raises(MachineError) as ei:
        load_machine(f)
    assert str(ei.value).startswith(f"{f}:{_line(text, 'switch_delay_s')}: consumer "
                                    '"clamp": switch_delay_s must be a number')


def test_a_toml_syntax_error_names_line_and_column(tmp_path):
    f = write(tmp_path, GOOD.replace("scan_ms = 5", "scan_ms = = 5"))
    with pytest.raises(MachineError) as ei:
        load_machine(f)
    assert str(ei.value).startswith(f"{f}:{_line(GOOD, 'scan_ms')}:11: not valid TOML")
    f.write_bytes(GOOD.replace('"station"', '"st\xe4tion"').encode("latin-1"))
    with pytest.raises(MachineError, match=r"station\.toml:3:11: not UTF-8"):
        load_machine(f)


def test_an_unknown_key_names_the_one_meant_or_else_lists_them(tmp_path):
    with pytest.raises(MachineError) as ei:
        load_machine(write(tmp_path, GOOD.replace("bore_mm = 32", "bor_mm = 32")))
    assert str(ei.value).endswith("unknown key 'bor_mm'; did you mean 'bore_mm'?")
    with pytest.raises(MachineError) as ei:
        load_machine(write(tmp_path, GOOD.replace("bore_mm = 32", "Bore_mm = 32")))
    assert str(ei.value).endswith("did you mean 'bore_mm'?")
    with pytest.raises(MachineError) as ei:
        load_machine(write(tmp_path, GOOD.replace("Cd = 0.8", "Cd = 0.8\ncolour = 1")))
    assert "unknown key 'colour' (known: C, Cd, a, air_factor, b, bore_mm," in str(ei.value)


@pytest.mark.parametrize("key, value, expected", [
    ("supply_bar_g", 87, ("supply_bar_g = 87 bar(g) is outside the plausible 1-16 bar(g); "
                         "psi typed as bar? 87 psi is 6.00 bar(g)")),
    ("stroke_time_s", "[150, 0.2]", ("stroke_time_s = 150 s is outside the plausible "
                                    "0.005-30 s; ms typed as s? 150 ms is 0.15 s")),
    ("stroke_mm", 0.5, ("stroke_mm = 0.5 mm is outside the plausible 1-6000 mm; cm typed as "
                       "mm? 0.5 cm is 5 mm")),
    ("tube_length_m", 700, "mm typed as m? 700 mm is 0.7 m"),
    ("ambient_c", 68, "°F typed as °C? 68 °F is 20 °C"),
])
def test_a_value_outside_the_plausible_range_is_a_warning_at_its_line(tmp_path, key, value,
                                                                      expected):
    old = next(ln for ln in GOOD.split("\n") if ln.startswith(f"{key} =")) if key != \
        "ambient_c" else "scan_ms = 5"
    new = f"{key} = {value}" if key != "ambient_c" else f"scan_ms = 5\nambient_c = {value}"
    text = GOOD.replace(old, new, 1)
    f = write(tmp_path, text)
    warnings = [w for w in load_machine(f).warnings if expected in w]
    assert len(warnings) == 1, load_machine(f).warnings
    assert warnings[0].startswith(f"{f}:{_line(text, f'{key} = {value}')}: ")


def test_plausible_values_give_no_warning(tmp_path):
    assert load_machine(write(tmp_path, GOOD)).warnings == []


def test_the_plausible_ranges_lie_inside_the_physical_ones():
    from plcpred.machine import schema
    for key, p in schema.PLAUSIBLE.items():
        low, high = schema.RANGES[key]
        assert low <= p.low < p.high <= high, key


def test_a_warning_from_a_sweep_or_a_merged_truth_has_no_line_it_cannot_know(tmp_path):
    """Data that is not the file's (a sweep's setting) is warned about without the file's
    line, which holds another value."""
    import tomllib

    from plcpred.machine import machine_from_data
    f = write(tmp_path, GOOD)
    data = tomllib.loads(GOOD)
    data["machine"]["supply_bar_g"] = 90
    warnings = machine_from_data(data, f).warnings
    assert warnings and warnings[0].startswith(f"{f}: [machine]: supply_bar_g = 90")


def test_a_machine_error_keeps_its_place_through_pickling():
    import pickle
    e = MachineError("m.toml", '[machine]', "x", table="machine", key="scan_ms", line=4,
                     column=2)
    back = pickle.loads(pickle.dumps(e))
    assert str(back) == str(e) == "m.toml:4:2: [machine]: x" and back.key == "scan_ms"


def test_the_errors_and_the_warning_the_docs_show_are_what_plcpred_says(tmp_path):
    """docs/reference/machine-file.md's error lines, made from its small example."""
    import re
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference"
           / "machine-file.md").read_text()
    example = doc.split("## A small example", 1)[1].split("```toml\n", 1)[1].split("```")[0]
    shown = doc.split("## Errors and warnings", 1)[1].split("```\n")
    errors, warning = shown[1].strip().split("\n"), shown[3].strip()
    (tmp_path / "station.st").write_text(ONE_OUTPUT)
    f = tmp_path / "station.toml"
    edits = [("stroke_mm = 25", "stroke_mm = 0"), ("bore_mm = 32", "bor_mm = 32"),
             ("scan_ms = 10", "scan_ms = = 10")]
    for (old, new), expected in zip(edits, errors, strict=True):
        f.write_text(example.replace(old, new, 1))
        with pytest.raises(MachineError) as ei:
            load_machine(f)
        assert str(ei.value).replace(str(f), "station.toml") == expected
    f.write_text(example.replace("supply_bar_g = 6.0", "supply_bar_g = 87"))
    got = [w.replace(str(f), "station.toml") for w in load_machine(f).warnings]
    assert re.sub("^warning: ", "", warning) in got


def test_a_signal_changed_after_loading_is_named_without_the_files_line(tmp_path):
    """The file's line holds another signal (a truth file's, a machine changed in
    memory): the error names the table and key, not a line that would mislead."""
    m = load_machine(write(tmp_path, GOOD))
    m.consumer("blow-off").valve = ["blower"]
    with pytest.raises(MachineError) as ei:
        check_against_program(m, parse_st(PROGRAM))
    assert str(ei.value).startswith(f"{tmp_path / 'station.toml'}: consumer \"blow-off\": "
                                    "valve 'blower'")


def test_outputs_named_in_no_air_draw_no_warning(tmp_path):
    text = GOOD.replace("supply_bar_g = 6.0", 'supply_bar_g = 6.0\nno_air = ["LAMP"]', 1)
    m = load_machine(write(tmp_path, text))
    assert m.no_air == ["LAMP"]
    warnings = check_against_program(m, parse_st(PROGRAM))
    assert not any("lamp" in w.lower() and "drives no consumer" in w for w in warnings)
    m = load_machine(write(tmp_path, text.replace('["LAMP"]', '["lamp_x"]')))
    with pytest.raises(MachineError, match=r"no_air 'lamp_x' is not a variable.*did you mean"):
        check_against_program(m, parse_st(PROGRAM))
    with pytest.raises(MachineError, match="no_air must be a list of outputs"):
        load_machine(write(tmp_path, text.replace('["LAMP"]', '"lamp"')))
