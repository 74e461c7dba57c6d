"""Vendor libraries: the shipped stubs, user libraries, namespaces and MEM* built-ins."""
import pytest

from plcpred.cli import main
from plcpred.machine import load_machine
from plcpred.parser import load_program, parse_st
from plcpred.sequencer import ExecutionError, unfold
from plcpred.sequencer.executor import ProgramInstance

MS = 1_000_000


def run_file(path, scans, setup=None, scan_ms=10, **kw):
    """(program instance, per-scan snapshots of the PROGRAM) of a program file."""
    inst = ProgramInstance(load_program(path, **kw))
    prog = inst.programs[0]
    for k in range(scans):
        if setup:
            setup(prog, k)
        inst.guard(inst.scan, k * scan_ms * MS)
        yield k, prog


def write(tmp_path, name, text):
    f = tmp_path / name
    f.parent.mkdir(parents=True, exist_ok=True)
    f.write_text(text)
    return f


def test_codesys_util_blink_high_then_low_and_namespaced(tmp_path, capsys):
    f = write(tmp_path, "p.st", "PROGRAM P\nVAR\n  b : Util.BLINK;\n  go, q : BOOL;\nEND_VAR\n"
              "b(ENABLE := go, TIMEHIGH := T#30MS, TIMELOW := T#20MS, OUT => q);\nEND_PROGRAM\n")
    outs = [p.Q for _, p in run_file(f, 14, lambda p, k: setattr(p, "GO", k >= 2))]
    # ENABLE from 20 ms: TRUE for 30 ms, FALSE for 20 ms, TRUE again, ...
    assert outs == [False, False, True, True, True, False, False, True, True, True, False,
                    False, True, True]
    assert main(["check", str(f)]) == 0
    assert "warning" not in capsys.readouterr().err     # the stub's own findings stay out


def test_motion_move_completes_after_its_trapezoidal_profile(tmp_path):
    f = write(tmp_path, "m.st", """PROGRAM P
VAR
    ax : AXIS_REF;
    pwr : MC_Power;
    mv : Tc2_MC2.MC_MoveAbsolute;
    rel : MC_MoveRelative;
    go, done, done2 : BOOL;
END_VAR
pwr(Axis := ax, Enable := TRUE);
mv(Axis := ax, Execute := go, Position := 100.0, Velocity := 50.0, Acceleration := 100.0,
   Deceleration := 100.0, Done => done);
rel(Axis := ax, Execute := done, Distance := -10.0, Velocity := 50.0, Acceleration := 100.0,
    Deceleration := 100.0, Done => done2);
END_PROGRAM
""")
    done_at = done2_at = None
    for k, p in run_file(f, 400, lambda p, k: setattr(p, "GO", k >= 1)):
        if p.DONE and done_at is None:
            done_at = k
        if p.DONE2 and done2_at is None:
            done2_at = k
    # 0 -> 100 at 50/s with 100/s2 ramps: 0.5 s + 75/50 s + 0.5 s = 2.5 s after the edge
    assert (done_at - 1) * 10 == pytest.approx(2500, abs=10)
    # then 10 back, a triangle: 2 * sqrt(10 / 100) s = 0.632 s
    assert (done2_at - done_at) * 10 == pytest.approx(632, abs=10)
    assert p.AX.ACTUALPOSITION == pytest.approx(90.0)


def test_user_library_by_option_and_by_machine_file(tmp_path, capsys, samples_dir):
    lib = write(tmp_path, "libs/ValveLib/FB_Pulse.st", """FUNCTION_BLOCK FB_Pulse
VAR_INPUT
    bStart : BOOL;
    tOn : TIME;
END_VAR
VAR_OUTPUT
    bValve : BOOL;
END_VAR
VAR
    tp : TP;
END_VAR
tp(IN := bStart, PT := tOn, Q => bValve);
END_FUNCTION_BLOCK
""").parent
    prog = write(tmp_path, "station.st", """PROGRAM Main
VAR
    bGo AT %IX0.0 : BOOL;
    bOut AT %QX0.0 : BOOL;
    fb : ValveLib.FB_Pulse;
END_VAR
fb(bStart := bGo, tOn := T#300MS, bValve => bOut);
END_PROGRAM
""")
    assert main(["check", str(prog)]) == 1
    assert "FB_Pulse" in capsys.readouterr().err
    assert main(["check", "--lib", str(lib), str(prog)]) == 0
    machine = write(tmp_path, "station.toml", """[machine]
program = "station.st"
libraries = ["libs/ValveLib/"]
supply_bar_g = 6.0

[[input]]
signal = "bGo"
period_s = 2.0
pulse_ms = 50

[[consumer]]
name = "blow"
kind = "nozzle"
orifice_mm = 1.0
Cd = 0.8
valve = "bOut"
""")
    tl = unfold(load_machine(machine), "10s")
    assert tl.count_rising("bOut") == 5
    assert tl.on_time_s("bOut") == pytest.approx(1.5, abs=0.05)
    bad = write(tmp_path, "bad.toml", machine.read_text().replace("libs/ValveLib/", "nope/"))
    with pytest.raises(Exception, match=r"\[machine\].*library 'nope/' not found"):
        load_machine(bad)


SRC_MEM = """TYPE ST_P : STRUCT a : INT; b : ARRAY[0..2] OF BOOL; END_STRUCT END_TYPE
PROGRAM P
VAR
    x, y : ST_P;
    arr1, arr2 : ARRAY[1..3] OF INT;
    n : INT;
    same, differ, same2 : DINT;
END_VAR
x.a := 7; x.b[1] := TRUE; arr1[2] := 5;
MEMCPY(ADR(y), ADR(x), SIZEOF(x));
MEMCPY(destAddr := ADR(arr2), srcAddr := ADR(arr1), n := SIZEOF(arr1));
same := MEMCMP(ADR(x), ADR(y), SIZEOF(x));
MEMSET(ADR(x), 0, SIZEOF(x));
differ := MEMCMP(ADR(x), ADR(y), SIZEOF(x));
Tc2_System.MEMCPY(ADR(n), ADR(arr1[2]), 2);
same2 := MEMCMP(ADR(n), ADR(arr2[2]), 2);
END_PROGRAM
"""


def test_memcpy_memset_memcmp_on_whole_values(tmp_path):
    f = write(tmp_path, "mem.st", SRC_MEM)
    _, p = list(run_file(f, 1))[-1]
    assert (p.Y.A, list(p.Y.B), list(p.ARR2)) == (7, [False, True, False], [0, 5, 0])
    assert (p.X.A, list(p.X.B)) == (0, [False, False, False])
    assert (p.SAME, p.DIFFER, p.N, p.SAME2) == (0, 1, 5, 0)
    f = write(tmp_path, "bad.st", SRC_MEM.replace("ADR(y), ADR(x)", "ADR(arr1), ADR(x)"))
    with pytest.raises(ExecutionError, match="whole values of one type"):
        list(run_file(f, 1))


def test_a_name_the_program_defines_wins_over_a_library(tmp_path):
    f = write(tmp_path, "p.st", """FUNCTION_BLOCK BLINK
VAR_OUTPUT
    OUT : BOOL := TRUE;
END_VAR
END_FUNCTION_BLOCK
PROGRAM P
VAR
    b : BLINK;
    q : BOOL;
END_VAR
b(OUT => q);
END_PROGRAM
""")
    prog = load_program(f)
    assert [p.name for p in prog.pous] == ["BLINK", "P"]
    assert parse_st(f.read_text(), str(f)) == load_program(f, libraries=False)


def test_tc2_utilities_trim_and_cpu_counter(tmp_path):
    f = write(tmp_path, "t.st", """PROGRAM P
VAR
    s, r : STRING := '   padded  ';
    cnt : GETCPUCOUNTER;
    lo : UDINT;
END_VAR
s := F_LTrim('   padded  ');
r := F_RTrim(s);
cnt();
lo := cnt.cpuCntLoDW;
END_PROGRAM
""")
    snaps = [(p.S, p.R, p.LO) for _, p in run_file(f, 3)]
    assert [x[:2] for x in snaps] == [("padded  ", "padded")] * 3
    assert [x[2] for x in snaps] == [0, 100_000, 200_000]   # 100 ns ticks at 10 ms scans


def test_allow_external_turns_names_of_missing_libraries_into_warnings(tmp_path, capsys):
    f = write(tmp_path, "p.st", """FUNCTION_BLOCK FB_Test EXTENDS TcUnit.FB_TestSuite IMPLEMENTS I_Missing
VAR
    log : FsCommon.FB_Logger;
    n : INT;
END_VAR
n := GeneralConstants.MAX_AXES + F_Missing(n);
END_FUNCTION_BLOCK
""")
    assert main(["check", str(f)]) == 1
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "warning:" not in line]
    assert len(errors) == 5                  # type, EXTENDS, IMPLEMENTS, qualifier, function
    assert main(["check", "--allow-external", str(f)]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("taken as external") == 5 and "ok (6 warnings)" in captured.out
    # a real mistake stays an error
    f.write_text(f.read_text().replace("n := ", "nn := "))
    assert main(["check", "--allow-external", str(f)]) == 1


def test_a_library_file_plcpred_cannot_read_leaves_the_rest_of_the_library(tmp_path, capsys):
    lib = tmp_path / "libs" / "ShopLib"
    write(tmp_path, "libs/ShopLib/FB_Good.st", "FUNCTION_BLOCK FB_Good\nVAR_OUTPUT q : BOOL; "
          "END_VAR\nq := TRUE;\nEND_FUNCTION_BLOCK\n")
    write(tmp_path, "libs/ShopLib/FB_Odd.st", "FUNCTION_BLOCK FB_Odd\nVAR n : INT; END_VAR\n"
          "n := n + * 1;\nEND_FUNCTION_BLOCK\n")
    good = write(tmp_path, "good.st", "PROGRAM P\nVAR fb : FB_Good; b : BOOL; END_VAR\n"
                 "fb(); b := fb.q;\nEND_PROGRAM\n")
    odd = write(tmp_path, "odd.st", "PROGRAM P\nVAR fb : FB_Odd; END_VAR\nfb();\nEND_PROGRAM\n")
    assert main(["check", "--lib", str(lib), str(good)]) == 0
    capsys.readouterr()
    assert main(["check", "--lib", str(lib), str(odd)]) == 1
    err = capsys.readouterr().err
    assert "unknown type 'FB_Odd'" in err
    assert "library file plcpred could not read" in err and "FB_Odd.st:3:" in err


def test_axis_status_set_position_and_tc2_math(tmp_path):
    f = write(tmp_path, "m.st", """PROGRAM P
VAR
    ax : AXIS_REF;
    pwr : MC_Power;
    setPos : MC_SetPosition;
    mv : MC_MoveAbsolute;
    go, set, moving, standstill : BOOL;
    state : MC_AxisStates;
    f1, f2, c1, m1 : LREAL;
    sev : TcEventSeverity := TcEventSeverity.Warning;
END_VAR
pwr(Axis := ax, Enable := TRUE, BufferMode := MC_BufferMode.MC_Aborting);
setPos(Axis := ax, Execute := set, Position := 40.0);
mv(Axis := ax, Execute := go, Position := 50.0, Velocity := 10.0);
moving := ax.Status.Moving;
standstill := ax.Status.StandStill;
state := ax.Status.MotionState;
f1 := FLOOR(-1.5); f2 := Tc2_Math.FLOOR(2.0); c1 := CEIL(1.25); m1 := MODABS(-30.0, 360.0);
END_PROGRAM
""")
    trace = []
    for k, p in run_file(f, 120, lambda p, k: (setattr(p, "SET", k >= 1),
                                               setattr(p, "GO", k >= 3))):
        trace.append((p.AX.ACTUALPOSITION, p.MOVING, p.STANDSTILL, int(p.STATE)))
    standstill, discrete = 2, 6        # MC_AXISSTATE_STANDSTILL, _DISCRETEMOTION
    assert trace[0] == (0.0, False, True, standstill)
    assert trace[1][0] == 40.0                            # set, not moved
    # 40 -> 50 at 10/s (no ramps): 1 s after the edge at scan 3
    assert trace[50] == (40.0, True, False, discrete)
    assert trace[110] == (50.0, False, True, standstill)
    assert (p.F1, p.F2, p.C1, p.M1, int(p.SEV)) == (-2.0, 2.0, 2.0, 330.0, 2)


def test_a_variable_named_like_a_library_type_and_a_gvl_of_two_blocks(tmp_path, capsys):
    # TcUnit: ``GetCpuCounter : GETCPUCOUNTER;`` (the variable does not declare the
    # type) in a GVL with a second, CONSTANT block read as GVL_X.constant
    lib = tmp_path / "libs" / "XLib"
    write(tmp_path, "libs/XLib/GVL_X.TcGVL", """<?xml version="1.0" encoding="utf-8"?>
<TcPlcObject Version="1.1.0.1"><GVL Name="GVL_X"><Declaration><![CDATA[VAR_GLOBAL
  GetCpuCounter : GETCPUCOUNTER;
END_VAR
VAR_GLOBAL CONSTANT
  Scale : LREAL := 1.0E-7;
END_VAR]]></Declaration></GVL></TcPlcObject>
""")
    prog = write(tmp_path, "p.st", "PROGRAM P\nVAR t : LREAL; END_VAR\n"
                 "GVL_X.GetCpuCounter();\nt := UDINT_TO_LREAL(GVL_X.GetCpuCounter.cpuCntLoDW)"
                 " * GVL_X.Scale;\nEND_PROGRAM\n")
    assert main(["check", "--lib", str(lib), str(prog)]) == 0, capsys.readouterr().err


def test_rtc_runs_on_from_its_preset_and_a_library_enumeration_named_by_value(tmp_path):
    f = write(tmp_path, "r.st", """PROGRAM P
VAR r : RTC; go, q : BOOL; now : DT; l : LOGGER; END_VAR
r(IN := go, PDT := DT#2026-11-24-08:00:00, Q => q, CDT => now);
l(TRIG := go, MSG := 'tick', LEVEL := DEBUG);
END_PROGRAM
""")
    t0 = None
    got = []
    for k, p in run_file(f, 5, lambda p, k: setattr(p, "GO", k >= 1), scan_ms=500):
        t0 = t0 or p.NOW
        got.append((p.Q, p.NOW - t0))
    # the preset holds until IN rises at scan 1, then the clock runs on 0.5 s a scan
    assert got == [(False, 0), (True, 0), (True, 500 * MS), (True, 1000 * MS),
                   (True, 1500 * MS)]


def test_char_codes_to_lower_case_and_codesys_type_classes(tmp_path):
    f = write(tmp_path, "c.st", """PROGRAM P
VAR s : STRING; b : BYTE; c : STRING(1); t : TypeClass; u : __SYSTEM.TYPE_CLASS; END_VAR
s := F_ToLCase('AbC-Z9');
b := CHAR_TO_BYTE(STRING_TO_CHAR('A'));
c := CHAR_TO_STRING(BYTE_TO_CHAR(b + 1));
t := IBaseLibrary.TypeClass.TYPE_LREAL;
u := TYPE_CLASS.TYPE_INT;
END_PROGRAM
""")
    (_, p), = run_file(f, 1)
    assert (p.S, p.B, p.C, int(p.T), int(p.U)) == ("abc-z9", 65, "B", 15, 7)


def test_twincat_system_info_list_is_there_for_every_project(tmp_path):
    # TcUnit reads the task's cycle count and the project name from it
    f = write(tmp_path, "si.st", """PROGRAM P
VAR
    GetCurrentTaskIndex : GETCURTASKINDEX;
    n : UDINT;
    s : STRING;
END_VAR
GetCurrentTaskIndex();
n := TwinCAT_SystemInfoVarList._TaskInfo[GetCurrentTaskIndex.index].CycleCount;
s := CONCAT(STR1 := TwinCAT_SystemInfoVarList._AppInfo.ProjectName, STR2 := '.');
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    inst = ProgramInstance(load_program(f))
    inst.guard(inst.scan, 0)
    prog = inst.programs[0]
    assert (prog.N, prog.S) == (0, "PLC.")


def test_oscat_multime_from_a_module_the_project_does_not_have(tmp_path):
    # OpenPLC copies of single OSCAT modules call MULTIME from the time module
    f = write(tmp_path, "m.st", """PROGRAM P
VAR_OUTPUT a, b : TIME; END_VAR
a := MULTIME(T#2s, 1.5);
b := multime(t := T#100ms, M := 0.25);
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    inst = ProgramInstance(load_program(f))
    inst.guard(inst.scan, 0)
    prog = inst.programs[0]
    assert (prog.A, prog.B) == (3_000_000_000, 25_000_000)      # ns


def _scan(path, scans=1):
    inst = ProgramInstance(load_program(path))
    for k in range(scans):
        inst.guard(inst.scan, k * 10 * MS)
    return inst.programs[0]


def test_sysfile_never_opens_a_host_file_and_nested_namespaces_resolve(tmp_path, capsys):
    # TcUnit's FB_FileControl, reduced: SysFile.SysTypes.* and SysDir.CmpErrors.Errors.*
    # are namespaces inside namespaces
    f = write(tmp_path, "f.st", f"""PROGRAM P
VAR
    h : SysFile.SysTypes.RTS_IEC_HANDLE;
    res, res2 : SysFile.SysTypes.RTS_IEC_RESULT;
    mode : SysFile.ACCESS_MODE := SysFile.ACCESS_MODE.AM_APPEND_PLUS;
    n : SysFile.SysTypes.RTS_IEC_SIZE;
    buf : ARRAY[0..9] OF BYTE;
    invalid : BOOL;
END_VAR
h := SysFile.SysFileOpen(szFile := '{tmp_path / "made.txt"}', am := mode, pResult := ADR(res));
invalid := h = SysFile.SysTypes.RTS_INVALID_HANDLE;
IF NOT invalid THEN
    n := SysFile.SysFileWrite(hFile := h, pbyBuffer := ADR(buf), ulSize := SIZEOF(buf),
                              pResult := ADR(res2));
ELSE
    res2 := SysDir.CmpErrors.Errors.ERR_INVALID_HANDLE;
END_IF
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f)
    assert p.INVALID and p.RES == 0xC and p.RES2 == 0x14     # CmpErrors.h numbers
    assert not (tmp_path / "made.txt").exists()


def test_format_string_and_ring_buffer_driven_by_its_actions(tmp_path):
    f = write(tmp_path, "u.st", """PROGRAM P
VAR
    fmt : FB_FormatString;
    bad : FB_FormatString;
    ring : FB_MemRingBuffer;
    buf : ARRAY[0..99] OF BYTE;
    msg : ARRAY[0..39] OF BYTE;
    ok : ARRAY[1..6] OF BOOL;
    count : UDINT;
END_VAR
fmt(sFormat := 'axis %d at %.2f mm: %s (100%%)', arg1 := F_DINT(-3), arg2 := F_LREAL(1.5),
    arg3 := F_STRING('ok'));
bad(sFormat := '%d and %d', arg1 := F_WORD(7));
(* an entry costs its bytes and 4: two of 44 fit in 100, a third does not *)
ring.A_AddTail(pWrite := ADR(msg), cbWrite := SIZEOF(msg), pBuffer := ADR(buf),
               cbBuffer := SIZEOF(buf), bOk => ok[1]);
ring.A_AddTail(pWrite := ADR(msg), cbWrite := SIZEOF(msg), pBuffer := ADR(buf),
               cbBuffer := SIZEOF(buf), bOk => ok[2]);
ring.A_AddTail(pWrite := ADR(msg), cbWrite := SIZEOF(msg), pBuffer := ADR(buf),
               cbBuffer := SIZEOF(buf), bOk => ok[3]);
count := ring.nCount;
ring.A_RemoveHead(pRead := ADR(msg), cbRead := SIZEOF(msg), pBuffer := ADR(buf),
                  cbBuffer := SIZEOF(buf));
ok[4] := ring.bOk;
ring.A_RemoveHead(pRead := ADR(msg), cbRead := SIZEOF(msg));
ok[5] := ring.bOk;
ring.A_RemoveHead(pRead := ADR(msg), cbRead := SIZEOF(msg));
ok[6] := ring.bOk;
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f)
    assert p.FMT.SOUT == "axis -3 at 1.5 mm: ok (100%)" and not p.FMT.BERROR
    assert p.BAD.BERROR and p.BAD.SOUT == "7 and "
    assert list(p.OK) == [True, True, False, True, True, False]
    assert p.COUNT == 2 and p.RING.NCOUNT == 0 and p.RING.CBSIZE == 0


def test_coe_read_is_busy_for_one_call_then_fails_and_drive_address(tmp_path):
    f = write(tmp_path, "e.st", """PROGRAM P
VAR
    rd : FB_EcCoESdoRead;
    code : UDINT := 7;
    n : INT;
    busy : ARRAY[1..3] OF BOOL;
    axis : AXIS_REF;
    addr : MC_ReadDriveAddress;
    id : DWORD;
END_VAR
n := n + 1;
rd(sNetId := '', nSlaveAddr := 1001, nIndex := 16#603F, nSubIndex := 0,
   pDstBuf := ADR(code), cbBufLen := SIZEOF(code), bExecute := n >= 2);
busy[n] := rd.bBusy;
axis.DriveAddress.NcDriveId := 5;
addr(Axis := axis, Execute := TRUE);
id := addr.DriveAddress.NcDriveId;
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f, 3)
    assert list(p.BUSY) == [False, True, False]
    assert p.RD.BERROR and p.RD.NERRID == 6 and p.CODE == 7
    assert p.ADDR.DONE and p.ID == 5


def test_json_sax_writer_document(tmp_path):
    f = write(tmp_path, "j.st", """PROGRAM P
VAR
    w : FB_JsonSaxWriter;
    dom : FB_JsonDomParser;
    root, dev : SJsonValue;
    doc : STRING(255);
END_VAR
w.ResetDocument();
w.StartObject();
w.AddKey('name');
w.AddString('ax "1"');
w.AddKey('pos');
w.AddLreal(1.5);
w.AddKey('list');
w.StartArray();
w.AddDint(-2);
w.AddBool(TRUE);
w.AddNull();
w.EndArray();
w.EndObject();
doc := w.GetDocument();
root := dom.NewDocument();
dev := dom.AddObjectMember(root, 'dev');
dom.AddIntMember(v := dev, member := 'id', value := 3,);
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f)
    assert p.DOC == '{"name":"ax \\"1\\"","pos":1.5,"list":[-2,true,null]}'
    assert p.DEV != p.ROOT != 0


def test_a_library_enum_value_named_through_the_library_namespace(tmp_path, capsys):
    # TcUnit: IBaseLibrary.TYPE_BIT (the value, its enumeration not named)
    f = write(tmp_path, "t.st", """PROGRAM P
VAR c : DINT; END_VAR
c := IBaseLibrary.TYPE_BIT;
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    assert _scan(f).C == 1


def test_file_blocks_never_reach_a_file_and_strings_behind_pointers(tmp_path, capsys):
    f = write(tmp_path, "fl.st", f"""PROGRAM P
VAR
    fo : FB_FileOpen;
    busy : ARRAY[1..3] OF BOOL;
    n : INT;
    a : STRING := 'hello world';
    b : STRING;
    c : STRING := 'ab';
    len_a : DINT;
    area : E_TcMemoryArea;
END_VAR
n := n + 1;
fo(sNetId := '', sPathName := '{tmp_path / "made.csv"}',
   nMode := FOPEN_MODEWRITE OR FOPEN_MODETEXT, ePath := PATH_GENERIC, bExecute := TRUE);
busy[n] := fo.bBusy;
len_a := LEN2(ADR(a));
STRNCPY(ADR(b), ADR(a), 6);
STRNCAT(ADR(c), ADR(a), 5);
area := F_CheckMemoryArea(ADR(a), 1);
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f, 3)
    assert list(p.BUSY) == [True, False, False] and p.FO.BERROR and p.FO.NERRID == 0x70C
    assert not (tmp_path / "made.csv").exists()
    assert (p.LEN_A, p.B, p.C) == (11, "hello", "abhe")
    assert int(p.AREA) == 0     # Unknown: plcpred cannot tell where memory lies


def test_csv_fields_and_the_buffer_writer(tmp_path, capsys):
    f = write(tmp_path, "csv.st", """PROGRAM P
VAR
    w : FB_CSVMemBufferWriter;
    line : STRING;
    q, back, plain : STRING;
    ok : ARRAY[1..3] OF BOOL;
END_VAR
q := STRING_TO_CSVFIELD('say "hi"', TRUE);
back := CSVFIELD_TO_STRING(q, TRUE);
plain := STRING_TO_CSVFIELD('a;b', FALSE);
DEFAULT_CSV_FIELD_SEP := 16#2C;
w(eCmd := eEnumCmd_First, pBuffer := ADR(line), cbBuffer := 8, putValue := 'abc');
ok[1] := w.bOk;
w(eCmd := eEnumCmd_Next, pBuffer := ADR(line), cbBuffer := 8, putValue := 'de', bCRLF := TRUE);
ok[2] := w.bOk;
w(eCmd := eEnumCmd_Next, pBuffer := ADR(line), cbBuffer := 8, putValue := 'x');
ok[3] := w.bOk;
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f)
    assert (p.Q, p.BACK, p.PLAIN) == ('"say ""hi"""', 'say "hi"', "a;b")
    # 'abc' and its separator (4), 'de' with separator and CR LF (4): 8 bytes; then full
    assert list(p.OK) == [True, True, False] and p.W.CBSIZE == 8 and p.W.NFIELDS == 2


def test_wide_string_functions_are_the_string_functions(tmp_path):
    f = write(tmp_path, "w.st", """PROGRAM P
VAR w : WSTRING := "motion"; n, k : INT; l : WSTRING; END_VAR
n := WLEN(w);
l := WCONCAT(WLEFT(w, 3), WRIGHT(w, 2));
k := WFIND(w, "ion");
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f)
    assert (p.N, p.L, p.K) == (6, "moton", 4)


def test_numbers_as_hex_decimal_octal_and_binary_strings(tmp_path):
    f = write(tmp_path, "hx.st", """PROGRAM P
VAR s : ARRAY[1..7] OF STRING; END_VAR
s[1] := DWORD_TO_HEXSTR(16#1F, 4, FALSE);
s[2] := BYTE_TO_HEXSTR(255, 1, TRUE);
s[3] := DWORD_TO_DECSTR(1234, 6);
s[4] := DWORD_TO_BINSTR(5, 0);
s[5] := DWORD_TO_HEXSTR(0, 0, FALSE);
s[6] := DWORD_TO_OCTSTR(8, 1);
s[7] := Tc2_Utilities.WORD_TO_HEXSTR(16#ABCD, 2, TRUE);
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    assert list(_scan(f).S) == ["001F", "ff", "001234", "101", "", "10", "abcd"]


def test_time_zone_blocks_convert_by_the_bias_across_days_and_years(tmp_path):
    # lcls-twincat-motion's PMPS database block: local time to UTC with the zone read
    # from the system (here UTC, after one busy call)
    f = write(tmp_path, "tz.st", """PROGRAM P
VAR
    n : INT;
    busy : ARRAY[1..3] OF BOOL;
    getTz : FB_GetTimeZoneInformation;
    toUtc : FB_TzSpecificLocalTimeToSystemTime;
    toLocal : FB_SystemTimeToTzSpecificLocalTime;
    tz : ST_TimeZoneInformation;
    t, u, v : TIMESTRUCT;
    d : DT;
END_VAR
n := n + 1;
getTz(sNetID := '', bExecute := TRUE, tTimeout := T#10S);
busy[n] := getTz.bBusy;
t.wYear := 2023; t.wMonth := 12; t.wDay := 31; t.wHour := 23; t.wMinute := 30;
tz.bias := 60;                       (* UTC-1: UTC = local + 60 min *)
toUtc(in := t, tzInfo := tz);
u := toUtc.out;
t.wYear := 2024; t.wMonth := 3; t.wDay := 1; t.wHour := 0; t.wMinute := 30;
tz.bias := -90;                      (* UTC+1:30, from UTC back to local: Feb 29th *)
toLocal(in := t, tzInfo := tz);
t.wHour := 0; t.wMinute := 30;
tz.bias := 90;
toLocal(in := t, tzInfo := tz);
v := toLocal.out;
d := SYSTEMTIME_TO_DT(u);
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f, 3)
    assert list(p.BUSY) == [True, False, False]
    assert (p.GETTZ.TZID, p.GETTZ.TZINFO.BIAS) == (0, 0)
    u, v = p.U, p.V
    assert (u.WYEAR, u.WMONTH, u.WDAY, u.WHOUR, u.WMINUTE, u.WDAYOFWEEK) == (2024, 1, 1, 0, 30, 1)
    assert (v.WYEAR, v.WMONTH, v.WDAY, v.WHOUR, v.WMINUTE, v.WDAYOFWEEK) == (2024, 2, 29, 23, 0, 4)
    assert p.D == 1704069000 * 10 ** 9          # 2024-01-01T00:30:00Z (held in ns)


def test_ipc_diagnostics_never_reach_the_ipc(tmp_path):
    f = write(tmp_path, "ipc.st", """PROGRAM P
VAR
    reg : FB_IPCDiag_Register;
    rd : FB_IPCDiag_ReadParameter;
    os : STRING := 'unset';
    hr : HRESULT;
END_VAR
reg(bExecute := TRUE, tTimeout := T#1S);
rd(bExecute := TRUE, eParameterKey := E_IPCDiag_ParameterKey.OS_Name, fbRegister := reg);
hr := rd.GetParameter(pBuffer := ADR(os), nBufferSize := SIZEOF(os));
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f, 2)
    assert p.REG.BERROR and not p.REG.BVALID and p.REG.HRERRORCODE < 0     # FAILED()
    assert not p.RD.BVALID and p.HR < 0 and p.OS == "unset"


def test_softmotion_axis_power_with_regulator_and_reading_the_position(tmp_path):
    # CODESYS SoftMotion (SM3_Basic): AXIS_REF_SM3, MC_Power's bRegulatorOn/bDriveStart,
    # MC_ReadActualPosition
    f = write(tmp_path, "sm3.st", """PROGRAM P
VAR
    Drive : AXIS_REF_SM3;
    pw : MC_Power;
    mv : MC_MoveAbsolute;
    rd : MC_ReadActualPosition;
    pos : LREAL;
    regulator : BOOL := TRUE;
END_VAR
pw(Axis := Drive, Enable := TRUE, bRegulatorOn := regulator, bDriveStart := TRUE);
mv(Axis := Drive, Execute := pw.Status, Position := 100, Velocity := 1000,
   Acceleration := 10000, Deceleration := 10000);
rd(Axis := Drive, Enable := TRUE);
pos := rd.Position;
END_PROGRAM
""")
    assert main(["check", str(f)]) == 0
    p = _scan(f, 100)
    assert p.POS == 100.0 and p.MV.DONE and p.RD.VALID
    # the regulator off: the axis is not powered and never moves
    inst = ProgramInstance(load_program(f))
    inst.programs[0].REGULATOR = False
    for k in range(100):
        inst.guard(inst.scan, k * 10 * MS)
    assert not inst.programs[0].PW.STATUS and inst.programs[0].POS == 0.0


def test_the_stub_index_is_current_and_only_needed_stubs_are_read(tmp_path):
    # plcpred/libraries/index.json says which stub file declares what; a stub changed
    # without `python -m plcpred.parser.libraries --index` fails here
    import json

    import plcpred.parser.libraries as libs
    assert json.loads(libs.INDEX_FILE.read_text()) == libs.build_index()
    # a fresh process reads only the stub a program needs (here Tc2_Utilities's F_LTrim)
    f = write(tmp_path, "trim.st", "PROGRAM P\nVAR s : STRING; END_VAR\n"
              "s := F_LTrim('  x');\nEND_PROGRAM\n")
    import subprocess
    import sys
    code = ("import plcpred.parser.libraries as L\nfrom plcpred.parser import load_program\n"
            f"load_program({str(f)!r})\n"
            "print(L._shipped_file.cache_info().currsize, len(L._shipped_files()))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    parsed, stubs = map(int, r.stdout.split())
    # Tc2_Utilities, and Tc2_System for the T_MaxString it uses: two of the sixteen
    assert (parsed, stubs >= 10) == (2, True)
    assert _scan(f).S == "x"
