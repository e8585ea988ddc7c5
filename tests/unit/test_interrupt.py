"""An interrupted command keeps its work: SIGINT (Ctrl-C) or SIGTERM (a batch
scheduler's stop) during the solve or while the outputs are written ends the
run with exit status 130 / 143, one line saying what was kept, the converged
increments as a .pvd series and a complete summary.json with status
'interrupted'; no output file is ever left half-written."""

import json
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

#: the log line after which the signal is sent, per phase, and a wait after it
#: (the outputs of hertz-friction take over a second: 30 VTU files, tables, figures)
WAIT_FOR = {"solve": ("[base] increment 3 ", 0.0), "output": ("[base] converged", 0.3)}


def _interrupt(out, sig, phase):
    """Run hertz-friction (30 increments, no FD check) in a subprocess, send ``sig``
    once its log shows ``phase`` begun; (exit code, stderr lines)."""
    cmd = [sys.executable, "-m", "signorini.app.cli", "hertz-friction", "--no-fd",
           "--out", str(out)]
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                         env={**os.environ, "PYTHONUNBUFFERED": "1"})
    lines, sent = [], False
    deadline = time.monotonic() + 240
    for line in p.stderr:
        lines.append(line.rstrip("\n"))
        if not sent and WAIT_FOR[phase][0] in line:
            time.sleep(WAIT_FOR[phase][1])
            p.send_signal(sig)
            sent = True
        if time.monotonic() > deadline:
            p.kill()
            break
    code = p.wait(timeout=120)
    assert sent, "\n".join(lines[-20:])
    return code, lines


@pytest.mark.timeout(600)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("phase", ["solve", "output"])
def test_a_signal_keeps_the_converged_increments(tmp_path, sig, phase):
    out = tmp_path / "run"
    code, lines = _interrupt(out, sig, phase)
    assert code == 128 + sig, "\n".join(lines[-20:])
    said = [ln for ln in lines if ln.startswith("signorini: interrupted")]
    name = "SIGINT" if sig == signal.SIGINT else "SIGTERM"
    assert len(said) == 1 and f"by {name} during {phase}" in said[0], said
    assert "Traceback" not in "\n".join(lines)
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and name in s["reason"] and phase in s["reason"]
    n = s["converged_increments"]
    assert (n >= 3 and n < 30) if phase == "solve" else n == 30
    assert s["load_factor_reached"] == pytest.approx(n / 30)
    assert s["files"] == ["hertz_friction.pvd"] and f"{n} converged increments" in said[0]
    assert s["params"]["mu"] > 0 and s["mesh"]["nodes"] > 0 and "timings" in s
    # the series lists every converged increment, each VTU whole (parsed)
    sets = ET.parse(out / "hertz_friction.pvd").getroot().find("Collection")
    files = [d.get("file") for d in sets]
    assert len(files) == n
    for f in files:
        ET.parse(out / f)
    # no temporary file of an interrupted write is left
    assert not [f.name for f in out.iterdir() if ".partial" in f.name or f.name.startswith(".")]


#: a command whose run spends its time in one library call that releases the
#: interpreter's lock and never returns to Python for minutes (as a factorisation
#: or a compilation of a large problem does)
SLOW_COMMAND = '''
import hashlib, sys
from signorini.app import cli, registry
from signorini.app.runner import prepare_output

mod = type(sys)("slow_c")
mod.NAME = "slow-c"
def add_parser(sub):
    p = sub.add_parser("slow-c")
    p.add_argument("--out", required=True)
    p.add_argument("-q", "--quiet", action="store_true")
    p.add_argument("-v", "--verbose", action="store_true")
def execute(args):
    prepare_output(args.out)
    print("inside the library call", file=sys.stderr, flush=True)
    hashlib.pbkdf2_hmac("sha256", b"x", b"y", 2**31 - 1)  # many minutes
    return 0
mod.add_parser, mod.execute = add_parser, execute
sys.modules["slow_c"] = mod
registry.COMMANDS["slow-c"] = "slow_c"
sys.exit(cli.main(["slow-c", "--out", sys.argv[1]]))
'''


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_inside_a_long_library_call_ends_the_run(tmp_path, sig):
    """Python would run the handler only after the call returns (minutes here): the
    watchdog writes the report after its grace period and ends the process."""
    from signorini.app.cli import GRACE_S

    out = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-c", SLOW_COMMAND, str(out)], stderr=subprocess.PIPE,
                         stdout=subprocess.DEVNULL, text=True)
    for line in p.stderr:
        if "inside the library call" in line:
            break
    time.sleep(0.5)
    p.send_signal(sig)
    t0 = time.monotonic()
    try:
        code = p.wait(timeout=60)  # ended, not hours later
    finally:
        p.kill()
    waited = time.monotonic() - t0
    rest = p.stderr.read()
    assert code == 128 + sig, rest
    assert waited >= GRACE_S - 0.5  # the main thread had its chance first
    name = "SIGINT" if sig == signal.SIGINT else "SIGTERM"
    assert f"interrupted by {name}" in rest and "inside a library call" in rest, rest
    assert "Traceback" not in rest
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and name in s["reason"]


#: each command with options that make its solve take several seconds
LONG_RUNS = {
    "hertz": ["--refine", "2", "--no-fd"],
    "hertz-friction": ["--refine", "1", "--no-fd"],
    "hertz3d": ["--n-fine", "12", "--no-fd"],
    "forging": ["--mesh", "20x40", "--no-fd"],
    "forging3d": ["--mesh", "6x6", "--no-fd"],
    "cylinders": ["--refine", "2", "--no-fd"],
    "spheres": ["--n-fine", "12", "--no-fd"],
    "ironing": ["--no-fd"],
    "ironing3d": ["--no-fd"],
    "optimize-forging": ["--mu", "0.1", "--maxiter", "3"],
    "run": [os.path.join(os.path.dirname(__file__), "..", "..", "examples", "block.toml")],
}


def test_every_command_is_in_the_interrupt_table():
    from signorini.app import registry

    assert set(LONG_RUNS) == set(registry.SWEEPABLE)


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("delay", [2.5, 6.0], ids=["early", "later"])
@pytest.mark.parametrize("name", list(LONG_RUNS))
def test_sigterm_is_honoured_within_seconds_in_every_command(tmp_path, name, delay):
    """Whatever the phase (imports, mesh, compilation, factorisation, output), SIGTERM
    ends the command within seconds with 143 and an 'interrupted' summary, or
    the command had already finished (0), or had not begun (still importing). The
    faster test of the watchdog above covers the same code in CI."""
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "signorini.app.cli", name, *LONG_RUNS[name], "--out", str(out),
           "-q"]
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    time.sleep(delay)
    p.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    try:
        code = p.wait(timeout=60)
    finally:
        p.kill()
    err = p.stderr.read()
    assert code in (0, 143, -signal.SIGTERM), err
    assert "Traceback" not in err
    if code == -signal.SIGTERM:  # still importing Python's modules: ended by the default action,
        assert not out.exists()  # before the command began (nothing to keep)
    if code == 143:
        assert time.monotonic() - t0 < 30, err  # seconds, not the rest of the run
        if (out / "summary.json").exists():
            assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"


def test_a_streamed_series_leaves_an_interrupt_only_what_the_signal_cut_short(tmp_path,
                                                                               monkeypatch):
    """runner.stream_series (a run under mpiexec on several ranks, whose launcher
    kills an interrupted rank a second after its SIGTERM): the base solve writes
    each increment into its series as it converges; an interrupt's report then
    computes only the increment whose files the signal cut short, and the end of a
    run none."""
    import xml.etree.ElementTree as ET

    import numpy as np

    import signorini as sg
    from signorini import progress
    from signorini.app import runner
    from signorini.errors import Interrupted
    from signorini.post import files

    m = sg.rectangle(np.linspace(0, 1, 4), np.linspace(0, 1, 4))
    pb = sg.Problem(m, sg.LinearElastic("E", 0.3), {"E": 100.0, "q": 2.0},
                    fixed=(sg.Fixed("bottom", 1), sg.Fixed("left", 0)),
                    loads=(sg.Pressure("top", "q"),))
    computed = []
    real = files._fields
    monkeypatch.setattr(files, "_fields", lambda s, i: computed.append(i) or real(s, i))

    def signal_at_2(label, n, t):  # told before the runner's writer: increment 2 is not written
        if n == 2:
            raise Interrupted(signal.SIGTERM)

    runner.stream_series(True)
    try:
        out = runner.prepare_output(tmp_path / "cut")
        with progress.on_increment(signal_at_2), pytest.raises(Interrupted):
            runner.solve_or_report(out, "run", pb, {}, steps=4, wrt=["q"])
        assert computed == [0]
        assert "kept 2 converged increments (run.pvd)" in runner.report_interrupt(signal.SIGTERM)
        assert computed == [0, 1]
        s = json.loads((out / "summary.json").read_text())
        assert s["status"] == "interrupted" and s["converged_increments"] == 2
        assert s["files"] == ["run.pvd"]
        ds = ET.parse(out / "run.pvd").getroot().findall("./Collection/DataSet")
        assert [d.get("file") for d in ds] == ["run_0001.vtu", "run_0002.vtu"]
        assert sorted(p.name for p in out.iterdir()) == ["run.pvd", "run_0001.vtu",
                                                         "run_0002.vtu", "summary.json"]
        # a whole run: its series is written as it converges, and not again at the end
        computed.clear()
        out = runner.prepare_output(tmp_path / "whole")
        sol = runner.solve_or_report(out, "run", pb, {}, steps=3, wrt=["q"])
        assert computed == [0, 1, 2]
        runner.write_series(sol, out / "run.pvd")
        assert computed == [0, 1, 2]
        # a series the command does not write is not streamed
        out = runner.prepare_output(tmp_path / "none")
        runner.solve_or_report(out, "run", pb, {}, series=False, steps=3)
        assert not list(out.iterdir())
    finally:
        runner.stream_series(False)
    # a serial run writes its series at the end
    computed.clear()
    out = runner.prepare_output(tmp_path / "serial")
    sol = runner.solve_or_report(out, "run", pb, {}, steps=3)
    assert computed == []
    runner.write_series(sol, out / "run.pvd")
    assert computed == [0, 1, 2]
