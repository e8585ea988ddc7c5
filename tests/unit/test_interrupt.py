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
