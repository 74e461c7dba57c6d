"""Machine files and programs from untrusted places (a pull request checked in CI): every
bad input ends in a clear error (MachineError naming table and key, ProgramError naming
file:line:col) in bounded time and memory, never an internal error (exit 3).

* where files may be: under the machine file's folder (or a project's), regular files of
  bounded size, folders walked to a bound (plcpred.parser.files);
* how a file's bytes become text: byte order mark, XML declaration;
* numbers and markers read with str.isdigit(), which '²' passes and int() refuses.
"""
import codecs
import os
import stat
from pathlib import Path

import pytest

from plcpred.cli import main
from plcpred.errors import PlcpredError
from plcpred.machine import MachineError, load_machine
from plcpred.parser import ProgramError, ir, load_program

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
SORTER = (SAMPLES / "openplc_sorter.st").read_text()


@pytest.fixture(autouse=True)
def no_allowed_roots(monkeypatch):
    """The rule itself: no folder allowed besides the machine file's (conftest allows the
    samples' for the other tests)."""
    monkeypatch.delenv("PLCPRED_ALLOW_ROOTS", raising=False)


def machine(folder: Path, program: str, extra: str = "", name: str = "m.toml") -> Path:
    path = folder / name
    path.write_text(f'[machine]\nname = "m"\nprogram = {program!r}\nsupply_bar_g = 6\n'
                    + extra)
    return path


def refused(path: Path, *words, **kw) -> str:
    with pytest.raises(MachineError) as e:
        load_machine(path, **kw)
    assert e.value.where == "[machine]", str(e.value)
    text = str(e.value)
    for w in words:
        assert w in text, text
    return text


# ------------------------------------------------------------------ where files may be

@pytest.mark.parametrize("program", ["/dev/zero", "/dev/stdin", "/dev/null", "/etc/hostname",
                                     "/proc/self/environ", "../outside.st", "/"])
def test_a_program_outside_the_machine_files_folder_is_refused(tmp_path, program):
    (tmp_path / "outside.st").write_text(SORTER)
    folder = tmp_path / "m"
    folder.mkdir()
    text = refused(machine(folder, program), "program", "outside")
    assert "SHELL" not in text and "PATH=" not in text     # nothing of what the file holds


def test_proc_environ_is_not_read_and_not_shown(tmp_path, monkeypatch):
    monkeypatch.setenv("PLCPRED_SECRET_TOKEN", "s3cr3t-value")
    path = machine(tmp_path, "/proc/self/environ")
    text = refused(path, "program")
    assert "s3cr3t" not in text and "PLCPRED_SECRET" not in text
    assert main(["timeline", str(path), "--horizon", "2s", "--out",
                 str(tmp_path / "o")]) in (1, 2)


@pytest.mark.parametrize("library", ["/", "/usr", "..", "../lib"])
def test_a_library_outside_the_machine_files_folder_is_refused(tmp_path, library):
    folder = tmp_path / "m"
    folder.mkdir()
    (tmp_path / "lib").mkdir()
    (folder / "p.st").write_text(SORTER)
    path = machine(folder, "p.st", f"libraries = [{library!r}]\n")
    refused(path, "libraries", "outside")
    assert main(["timeline", str(path), "--horizon", "2s", "--out",
                 str(tmp_path / "o")]) in (1, 2)


def test_a_symbolic_link_out_of_the_folder_is_refused(tmp_path):
    outside = tmp_path / "secret.st"
    outside.write_text(SORTER)
    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "p.st").symlink_to(outside)
    (folder / "lib").symlink_to(tmp_path)
    refused(machine(folder, "p.st"), "program", "outside")
    (folder / "q.st").write_text(SORTER)
    refused(machine(folder, "q.st", 'libraries = ["lib"]\n'), "libraries", "outside")
    # a link that stays inside is fine
    (folder / "r.st").symlink_to(folder / "q.st")
    assert load_machine(machine(folder, "r.st")).program_path == folder / "q.st"


def test_a_fifo_in_the_folder_is_refused_not_waited_on(tmp_path):
    os.mkfifo(tmp_path / "p.st")
    refused(machine(tmp_path, "p.st"), "program", "not a regular file")
    with pytest.raises(ProgramError, match="not a regular file"):
        load_program(tmp_path / "p.st")


def test_devices_are_not_read_as_programs():
    for device in ("/dev/zero", "/dev/null"):
        with pytest.raises(ProgramError, match="not a regular file"):
            load_program(device)


def test_an_allowed_root_lets_a_program_elsewhere_load(tmp_path, monkeypatch):
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "p.st").write_text(SORTER)
    folder = tmp_path / "m"
    folder.mkdir()
    path = machine(folder, "../shared/p.st")
    refused(path, "program", "outside")
    m = load_machine(path, allowed_roots=[tmp_path / "shared"])
    assert m.read_program().pou("sorter") is not None
    monkeypatch.setenv("PLCPRED_ALLOW_ROOTS", str(tmp_path / "shared"))
    assert load_machine(path).program_path == tmp_path / "shared" / "p.st"


def test_an_oversized_program_is_refused(tmp_path, monkeypatch):
    from plcpred.parser import files
    monkeypatch.setattr(files, "MAX_FILE_BYTES", 1000)
    (tmp_path / "p.st").write_text(SORTER + " " * 1000)
    refused(machine(tmp_path, "p.st"), "program", "1000 bytes")
    with pytest.raises(ProgramError, match="at most 1000 bytes"):
        load_program(tmp_path / "p.st")


def test_an_oversized_machine_file_is_refused(tmp_path):
    path = tmp_path / "m.toml"
    with open(path, "wb") as f:
        f.truncate(17_000_000)          # sparse: no disk used
    with pytest.raises(MachineError, match="16 MB"):
        load_machine(path)


def _project(folder: Path, include: str) -> Path:
    proj = folder / "P.plcproj"
    proj.write_text('<?xml version="1.0" encoding="utf-8"?>\n<Project><ItemGroup>\n'
                    f'<Compile Include="{include}"/>\n</ItemGroup></Project>\n')
    return proj


POU = ('<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject><POU Name="MAIN">'
       '<Declaration><![CDATA[PROGRAM MAIN\nVAR x : BOOL; END_VAR]]></Declaration>'
       '<Implementation><ST><![CDATA[x := NOT x;]]></ST></Implementation></POU>'
       '</TcPlcObject>\n')


@pytest.mark.parametrize("include", ["ABS", "../outside/Secret.TcPOU", "POUs/Link.TcPOU"])
def test_a_project_file_outside_the_project_is_refused(tmp_path, include):
    (tmp_path / "outside").mkdir()
    secret = tmp_path / "outside" / "Secret.TcPOU"
    secret.write_text(POU)
    proj_dir = tmp_path / "proj"
    (proj_dir / "POUs").mkdir(parents=True)
    (proj_dir / "POUs" / "Link.TcPOU").symlink_to(secret)
    proj = _project(proj_dir, str(secret) if include == "ABS" else include)
    with pytest.raises(ProgramError) as e:
        load_program(proj)
    assert (e.value.file, e.value.line) == (str(proj), 3)
    assert "<Compile Include=" in e.value.message
    # the folder of the project, and a machine file beside it naming it
    with pytest.raises(ProgramError):
        load_program(proj_dir)
    path = machine(proj_dir, "P.plcproj")
    with pytest.raises(ProgramError, match="Compile Include"):
        load_machine(path).read_program()
    assert main(["check", str(proj)]) == 1
    # a file inside the project still loads
    (proj_dir / "POUs" / "MAIN.TcPOU").write_text(POU)
    proj = _project(proj_dir, "POUs\\MAIN.TcPOU")
    assert load_program(proj, libraries=False).pou("MAIN") is not None


def test_a_folder_walk_is_bounded(tmp_path, monkeypatch):
    from plcpred.parser import files
    monkeypatch.setattr(files, "MAX_FOLDER_ENTRIES", 50)
    lib = tmp_path / "lib"
    lib.mkdir()
    for k in range(60):
        (lib / f"f{k}.txt").write_text("")
    (tmp_path / "p.st").write_text(SORTER)
    m = load_machine(machine(tmp_path, "p.st", 'libraries = ["lib"]\n'))
    with pytest.raises(ProgramError, match="more than 50 files"):
        m.read_program()
    with pytest.raises(ProgramError, match="more than 50 files"):
        load_program(lib)
    monkeypatch.setattr(files, "MAX_FOLDER_ENTRIES", 20_000)
    monkeypatch.setattr(files, "MAX_FOLDER_DEPTH", 3)
    deep = tmp_path / "deep"
    (deep / "a" / "b" / "c" / "d").mkdir(parents=True)
    with pytest.raises(ProgramError, match="nested more than 3 deep"):
        load_program(deep)


def test_a_library_named_on_the_command_line_is_walked_to_a_bound(tmp_path, monkeypatch,
                                                                   capsys):
    from plcpred.parser import files
    monkeypatch.setattr(files, "MAX_FOLDER_ENTRIES", 50)
    lib = tmp_path / "lib"
    lib.mkdir()
    for k in range(60):
        (lib / f"f{k}.txt").write_text("")
    (tmp_path / "p.st").write_text(SORTER)
    assert main(["check", str(tmp_path / "p.st"), "--lib", str(lib)]) == 1
    assert "more than 50 files" in capsys.readouterr().err


def test_every_sample_still_loads_with_nothing_allowed():
    for path in sorted(SAMPLES.glob("*.toml")) + sorted((SAMPLES / "prototype_rig").glob(
            "*.toml")):
        m = load_machine(path, allowed_roots=())
        assert m.read_program().pous, path


# ------------------------------------------------------------------ encodings

def _plcopen(declaration: str | None) -> str:
    head = f'<?xml version="1.0" encoding="{declaration}"?>\n' if declaration else ""
    return head + (
        '<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><dataTypes/><pous>\n'
        '<pou name="P" pouType="program"><interface><localVars><variable name="s"><type>'
        '<string/></type><initialValue><simpleValue value="\'caf\u00e9\'"/></initialValue>'
        '</variable></localVars></interface>\n<body><ST><xhtml:p '
        'xmlns:xhtml="http://www.w3.org/1999/xhtml"><![CDATA[s := \'d\u00e9j\u00e0 '
        '\u20ac\';]]></xhtml:p></ST></body></pou></pous></types></project>\n')


def _strings(program) -> tuple:
    pou = program.pou("P")
    return pou.var_blocks[0].decls[0].init.value, pou.body[0].value.value


@pytest.mark.parametrize("declared, codec, bom", [
    ("ISO-8859-15", "iso8859-15", b""), ("windows-1252", "cp1252", b""),
    ("UTF-16", "utf-16-le", codecs.BOM_UTF16_LE), ("UTF-16", "utf-16-be", codecs.BOM_UTF16_BE),
    ("UTF-32", "utf-32-le", codecs.BOM_UTF32_LE), (None, "utf-16-le", codecs.BOM_UTF16_LE),
    ("UTF-16", "utf-16-le", b"")])
def test_plcopen_files_are_decoded_once_as_they_say(tmp_path, declared, codec, bom):
    f = tmp_path / "p.xml"
    f.write_bytes(bom + _plcopen(declared).encode(codec))
    assert _strings(load_program(f, libraries=False)) == ("caf\u00e9", "d\u00e9j\u00e0 \u20ac")


def test_latin1_plcopen_is_not_decoded_twice(tmp_path):
    f = tmp_path / "p.xml"
    f.write_bytes(_plcopen("ISO-8859-1").replace("\u20ac", "E").encode("latin-1"))
    assert _strings(load_program(f, libraries=False)) == ("caf\u00e9", "d\u00e9j\u00e0 E")


def test_a_twincat_file_in_latin1_is_decoded_once(tmp_path):
    f = tmp_path / "MAIN.TcPOU"
    f.write_bytes(POU.replace('encoding="utf-8"', 'encoding="ISO-8859-1"').replace(
        "x := NOT x;", "x := NOT x; (* d\u00e9j\u00e0 *) s := 'caf\u00e9';").replace(
        "x : BOOL;", "x : BOOL; s : STRING;").encode("latin-1"))
    body = load_program(f, libraries=False).pou("MAIN").body
    assert body[1].value.value == "caf\u00e9"


@pytest.mark.parametrize("name", ["x-bogus", "zlib", "base64", "punycode", "rot13",
                                  "\u00e9t\u00e9"])
def test_an_unknown_encoding_is_an_error_at_the_declaration(tmp_path, name, capsys):
    f = tmp_path / "p.xml"
    f.write_bytes(_plcopen("NAME").replace("\u20ac", "E").encode("latin-1").replace(
        b"NAME", name.encode("utf-8")))
    with pytest.raises(ProgramError) as e:
        load_program(f)
    assert (e.value.file, e.value.line, e.value.col) == (str(f), 1, 31)
    assert "encoding" in e.value.message
    assert main(["check", str(f)]) == 1
    assert "Traceback" not in capsys.readouterr().err


def test_bytes_that_do_not_fit_the_declared_encoding_are_an_error(tmp_path):
    f = tmp_path / "p.xml"
    f.write_bytes(codecs.BOM_UTF16_LE + _plcopen("UTF-16").encode("utf-16-le")[:-1])
    with pytest.raises(ProgramError, match="not valid UTF-16"):
        load_program(f)


# ------------------------------------------------------------------ isdigit and markers

def _task(cycle: str) -> str:
    return ('<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject><Task Name="PlcTask">'
            f'<CycleTime>{cycle}</CycleTime><PouCall><Name>MAIN</Name></PouCall></Task>'
            '</TcPlcObject>\n')


@pytest.mark.parametrize("cycle", ["\u00b2", "1\u00b2", "\u0663", "\uff11"])
def test_a_cycle_time_that_is_no_ascii_number_is_an_error(tmp_path, cycle, capsys):
    f = tmp_path / "PlcTask.TcTTO"
    f.write_text(_task(cycle), encoding="utf-8")
    with pytest.raises(ProgramError, match="CycleTime"):
        load_program(f)
    assert main(["check", str(f)]) == 1
    assert "internal error" not in capsys.readouterr().err
    # ASCII digits still read
    f.write_text(_task("10000"))
    task = load_program(f, libraries=False).configurations[0].resources[0].tasks[0]
    assert task.params["INTERVAL"].value == 10_000_000


def _plcopen_vars(inner: str) -> str:
    return ('<?xml version="1.0" encoding="utf-8"?>\n'
            '<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><dataTypes/><pous>'
            f'<pou name="P" pouType="program"><interface><localVars>{inner}</localVars>'
            '</interface><body><ST><xhtml:p xmlns:xhtml="http://www.w3.org/1999/xhtml">'
            '<![CDATA[;]]></xhtml:p></ST></body></pou></pous></types></project>\n')


@pytest.mark.parametrize("count", ["\u00b2", "--5", "+-2", "\u0663"])
def test_a_repetition_value_that_is_no_ascii_number_is_an_error(tmp_path, count, capsys):
    f = tmp_path / "p.xml"
    f.write_text(_plcopen_vars(
        '<variable name="a"><type><array><dimension lower="0" upper="3"/><baseType><INT/>'
        f'</baseType></array></type><initialValue><arrayValue><value repetitionValue="{count}">'
        '<simpleValue value="1"/></value></arrayValue></initialValue></variable>'),
        encoding="utf-8")
    with pytest.raises(ProgramError, match="repetitionValue"):
        load_program(f)
    assert main(["check", str(f)]) == 1
    assert "internal error" not in capsys.readouterr().err


def test_a_subrange_without_its_range_is_an_error(tmp_path, capsys):
    f = tmp_path / "p.xml"
    f.write_text(_plcopen_vars(
        '<variable name="a"><type><subrangeSigned><baseType><INT/></baseType>'
        '</subrangeSigned></type></variable>'))
    with pytest.raises(ProgramError, match="range") as e:
        load_program(f)
    assert e.value.line == 2
    assert main(["check", str(f)]) == 1
    assert "internal error" not in capsys.readouterr().err


def _graphical_pou(action_text: str) -> str:
    return ('<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject><POU Name="MAIN">'
            '<Declaration><![CDATA[PROGRAM MAIN\nVAR x : BOOL; END_VAR]]></Declaration>'
            '<Implementation><SFC/></Implementation>\n<Action Name="A"><Implementation><ST>'
            f'<![CDATA[{action_text}]]></ST></Implementation></Action></POU></TcPlcObject>\n')


@pytest.mark.parametrize("marker", ["{{#99}}", "{{#\u00b2}}", "{{#0}}"])
def test_inline_code_that_looks_like_a_marker_stays_inline_code(tmp_path, marker, capsys):
    f = tmp_path / "MAIN.TcPOU"
    f.write_text(_graphical_pou(marker), encoding="utf-8")
    pou = load_program(f, libraries=False).pou("MAIN")
    # the graphical body is kept opaque; the action's own {{ }} is its inline code
    assert isinstance(pou.body[0], ir.Opaque) and "SFC body" in pou.body[0].what
    action = pou.actions[0].body[0]
    assert isinstance(action, ir.Opaque) and action.text == marker[2:-2]
    assert "SFC" not in action.what
    assert main(["check", str(f)]) == 0
    assert "internal error" not in capsys.readouterr().err


def test_beremiz_channel_that_is_no_ascii_number_is_left_out(tmp_path):
    (tmp_path / "plc.xml").write_text(_plcopen_vars('<variable name="x"><type><BOOL/></type>'
                                                    '</variable>'))
    (tmp_path / "beremiz.xml").write_text('<?xml version="1.0"?><BeremizRoot/>')
    hmi = tmp_path / "svghmi_0@svghmi"
    hmi.mkdir()
    (hmi / "baseconfnode.xml").write_text(
        '<?xml version="1.0" encoding="utf-8"?><BaseParams IEC_Channel="\u00b2" '
        'Name="svghmi_0"/>', encoding="utf-8")
    program = load_program(tmp_path / "plc.xml", libraries=False)
    assert not any(d.name.startswith("CURRENT_PAGE") for g in program.globals
                   for d in g.block.decls)
    (hmi / "baseconfnode.xml").write_text(
        '<?xml version="1.0"?><BaseParams IEC_Channel="1" Name="svghmi_0"/>')
    program = load_program(tmp_path / "plc.xml", libraries=False)
    assert any(d.name == "CURRENT_PAGE_1" for g in program.globals for d in g.block.decls)


def test_a_beremiz_extension_file_linked_out_of_the_project_is_not_read(tmp_path):
    (tmp_path / "secret.xml").write_text(
        '<?xml version="1.0"?><PyFile><variables>'
        '<variable name="Leaked" type="DINT" initial="1"/></variables></PyFile>')
    proj = tmp_path / "proj"
    proj.mkdir()
    (proj / "plc.xml").write_text(_plcopen_vars('<variable name="x"><type><BOOL/></type>'
                                                '</variable>'))
    (proj / "beremiz.xml").write_text('<?xml version="1.0"?><BeremizRoot/>')
    (proj / "py_ext_0@py_ext").mkdir()
    (proj / "py_ext_0@py_ext" / "pyfile.xml").symlink_to(tmp_path / "secret.xml")
    with pytest.raises(PlcpredError, match="outside"):
        load_program(proj / "plc.xml", libraries=False)


def test_no_internal_error_from_the_reported_cases_on_the_command_line(tmp_path, capsys):
    """Each case as the brief reproduced it, through the CLI: exit 1 or 2, never 3."""
    (tmp_path / "p.st").write_text(SORTER)
    for lib in ("/", "/usr"):
        path = machine(tmp_path, "p.st", f"libraries = [{lib!r}]\n", name="lib.toml")
        assert main(["timeline", str(path), "--horizon", "2s", "--out",
                     str(tmp_path / "o")]) in (1, 2), lib
    # (before the fix: the FIFO blocked for ever, /dev/zero grew without bound)
    os.mkfifo(tmp_path / "fifo.st")
    cases = {"environ.toml": "/proc/self/environ", "stdin.toml": "/dev/stdin",
             "fifo.toml": "fifo.st", "zero.toml": "/dev/zero"}
    for name, program in cases.items():
        path = machine(tmp_path, program, name=name)
        assert main(["timeline", str(path), "--horizon", "2s", "--out",
                     str(tmp_path / "o")]) in (1, 2), name
    assert "internal error" not in capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo.st").st_mode)


def test_an_allowed_root_lets_a_project_list_a_shared_file(tmp_path, monkeypatch):
    from plcpred.parser.files import extra_roots
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "MAIN.TcPOU").write_text(POU)
    (tmp_path / "proj").mkdir()
    proj = _project(tmp_path / "proj", "../shared/MAIN.TcPOU")
    with pytest.raises(ProgramError, match="outside"):
        load_program(proj, libraries=False)
    with extra_roots([tmp_path / "shared"]):
        assert load_program(proj, libraries=False).pou("MAIN") is not None
        path = machine(tmp_path / "proj", "P.plcproj")
        assert load_machine(path).read_program().pou("MAIN") is not None
    assert "PLCPRED_ALLOW_ROOTS" not in os.environ
