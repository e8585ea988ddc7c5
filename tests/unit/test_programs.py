"""Compiled programs kept between processes (signorini._programs): the same
results with and without them, bad entries rebuilt, concurrent writers safe."""

import dataclasses
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import signorini as sg
from signorini import _programs
from signorini.algorithms import stepping
from signorini.problems import hertz

SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    import signorini as sg
    from signorini import _programs
    from signorini.problems import hertz
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8), steps=2, wrt=["R", "E"])
    w = sol.increments[-1].w
    sys.stdout.write(" ".join([np.float64(w.sum()).hex(), np.float64(sol.increments[-1].sens["R"].sum()).hex(),
                               str(_programs.STATS["compiled"]), str(_programs.STATS["loaded"])]))
""")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache directory for this test; every model built afresh."""
    monkeypatch.setenv("SIGNORINI_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("SIGNORINI_PROGRAM_CACHE", raising=False)
    stepping._MODELS.clear()
    yield tmp_path / "programs"
    stepping._MODELS.clear()


def _solve():
    stepping._MODELS.clear()  # a new model: its programs come from the disk or XLA
    before = dict(_programs.STATS)
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8), steps=2, wrt=["R", "E"])
    counts = {k: _programs.STATS[k] - before.get(k, 0)
              for k in ("compiled", "loaded", "rebuilt", "saved", "evicted")}
    return sol, counts


def _same(a, b):
    for x, y in zip(a.increments, b.increments):
        np.testing.assert_array_equal(x.w, y.w)
        for n in ("R", "E"):
            np.testing.assert_array_equal(x.sens[n], y.sens[n])


def test_kept_programs_give_the_same_results(cache, monkeypatch):
    first, c1 = _solve()
    assert c1["compiled"] >= 5 and c1["saved"] == c1["compiled"] and c1["loaded"] == 0
    files = sorted(cache.glob("*.bin"))
    assert len(files) == c1["saved"]
    again, c2 = _solve()
    assert c2["compiled"] == 0 and c2["loaded"] == c1["compiled"]
    _same(first, again)
    monkeypatch.setenv("SIGNORINI_PROGRAM_CACHE", "0")  # switched off: compiled, not kept
    plain, c3 = _solve()
    assert c3["loaded"] == 0 and c3["saved"] == 0 and c3["compiled"] == c1["compiled"]
    _same(first, plain)


def test_corrupt_or_foreign_entries_are_rebuilt(cache):
    first, c1 = _solve()
    files = sorted(cache.glob("*.bin"), key=lambda p: p.stat().st_size)
    big, small = files[-1], files[0]
    blob = bytearray(big.read_bytes())
    blob[-100] ^= 0xFF  # a flipped byte in the executable
    big.write_bytes(bytes(blob))
    small.write_bytes(small.read_bytes()[:50])  # a truncated entry
    again, c2 = _solve()
    assert c2["rebuilt"] == 2 and c2["compiled"] == 2 and c2["loaded"] == c1["compiled"] - 2
    _same(first, again)
    # rewritten: the third run loads every program
    _, c3 = _solve()
    assert c3["compiled"] == 0 and c3["rebuilt"] == 0
    # an entry whose header names another code version is not used either
    magic, header, rest = big.read_bytes().split(b"\n", 2)
    big.write_bytes(magic + b"\n" + header.replace(b"|", b"|x", 1) + b"\n" + rest)
    _, c4 = _solve()
    assert c4["rebuilt"] == 1 and c4["compiled"] == 1


def test_another_code_version_is_a_miss(cache, monkeypatch):
    first, c1 = _solve()
    monkeypatch.setattr(_programs, "code_version", lambda: "another version of the code")
    again, c2 = _solve()
    assert c2["loaded"] == 0 and c2["compiled"] == c1["compiled"]  # not found, not misused
    _same(first, again)


def test_processes_filling_an_empty_cache_at_once(tmp_path):
    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(tmp_path)}
    env.pop("SIGNORINI_PROGRAM_CACHE", None)
    runs = [subprocess.Popen([sys.executable, "-c", SCRIPT], env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [r.communicate(timeout=600) for r in runs]
    assert all(r.returncode == 0 for r in runs), [o[1][-2000:] for o in outs]
    results = [o[0].split() for o in outs]
    assert results[0][:2] == results[1][:2]
    assert int(results[0][2]) > 0 and int(results[1][2]) > 0  # both compiled: nobody waited
    assert not list((tmp_path / "programs").glob(".tmp-*"))  # no half-written entry left
    third = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True,
                           timeout=600)
    assert third.returncode == 0, third.stderr[-2000:]
    out = third.stdout.split()
    assert out[:2] == results[0][:2] and out[2] == "0" and int(out[3]) > 0


def test_the_cache_keeps_to_its_size(cache, monkeypatch):
    """Past the cap the entries used least recently go (the one just written
    stays); a program above a quarter of the cap is not kept at all."""
    cache.mkdir(parents=True)
    for k in range(6):  # 6 entries of 1 MB, entry k used at time 1000 + k
        p = cache / f"e{k}.bin"
        p.write_bytes(bytes(2**20))
        os.utime(p, (1000 + k, 1000 + k))
    monkeypatch.setenv("SIGNORINI_CACHE_MAX_MB", "3.5")
    before = _programs.STATS["evicted"]
    _programs._evict(cache, keep=cache / "e0.bin")
    assert sorted(p.name for p in cache.glob("*.bin")) == ["e0.bin", "e4.bin", "e5.bin"]
    assert _programs.STATS["evicted"] - before == 3
    shutil.rmtree(cache)
    _, c1 = _solve()
    sizes = sorted(p.stat().st_size for p in cache.glob("*.bin"))
    shutil.rmtree(cache)
    cap = 4 * (sizes[-2] - 1000)  # the two largest programs are above a quarter of it
    monkeypatch.setenv("SIGNORINI_CACHE_MAX_MB", str(cap / 2**20))
    _, c2 = _solve()
    assert c2["compiled"] == c1["compiled"] and c2["saved"] == c1["saved"] - 2


def test_cache_command_shows_and_clears(cache, capsys):
    from signorini.app.cli import main

    _solve()
    n = len(list(cache.glob("*.bin")))
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert f"signorini programs: {cache}: {n} file(s)" in out and "JAX compilation cache" in out
    assert main(["cache", "--clear"]) == 0
    assert f"removed {n} file(s)" in capsys.readouterr().out
    assert not cache.exists() or not list(cache.glob("*.bin"))
    _, c = _solve()  # compiled again after clearing
    assert c["loaded"] == 0 and c["compiled"] > 0


def test_the_digest_does_not_depend_on_where_the_source_lives():
    """The same definitions loaded from two paths (two checkouts of a project) share
    their kept programs; another definition does not."""
    from signorini.model.identity import stable_digest, structure_key

    source = "load = lambda p: 2.0 * p['P']\n"
    other = "load = lambda p: 3.0 * p['P']\n"

    def problem(src, path):
        ns = {}
        exec(compile(src, path, "exec"), ns)
        pb = hertz.hertz_problem(n_fine=8, size=8)
        return dataclasses.replace(pb, loads=(sg.Pressure("top", ns["load"]),))

    a = stable_digest(structure_key(problem(source, "/home/a/project/loads.py")))
    b = stable_digest(structure_key(problem(source, "/srv/b/checkout/loads.py")))
    c = stable_digest(structure_key(problem(other, "/home/a/project/loads.py")))
    assert a is not None and a == b and a != c


def test_one_program_per_kind_serves_every_mesh_size(cache, monkeypatch):
    """The element and contact kernels of meshes larger than
    Model.WHOLE_MESH_UP_TO cells (lowered here to 0: small meshes, cheap) are
    compiled for their kind, not for a mesh: solving (with sensitivities) on a
    second, finer mesh builds none of the kind programs again, neither traced
    nor compiled nor loaded."""
    from collections import OrderedDict

    from signorini.algorithms import stepping
    from signorini.model.chunks import Chunked
    from signorini.model.kernels import Model

    monkeypatch.setattr(Model, "WHOLE_MESH_UP_TO", 0)
    monkeypatch.setattr(stepping, "_MODELS", OrderedDict())

    def kind_programs():
        return {(type(k).__name__, spec): len(p._compiled)
                for k in Chunked._shared_kinds.values() for spec, p in k._programs.items()}

    coarse, fine = hertz.hertz_problem(n_fine=8, size=8), hertz.hertz_problem(n_fine=12, size=8)
    assert fine.mesh.cells.shape[0] > coarse.mesh.cells.shape[0]
    sg.solve(coarse, steps=2, wrt=["R", "E"])
    first = kind_programs()
    assert {name for name, _ in first} == {"CellKernels", "NodeKernels"}
    before = _programs.STATS["compiled"] + _programs.STATS["loaded"]
    sol = sg.solve(fine, steps=2, wrt=["R", "E"])
    assert kind_programs() == first
    # what the second mesh did build: its own small programs (geometry, loads,
    # prescribed values, the DDM's contact pseudo-load), none of the kernels
    assert _programs.STATS["compiled"] + _programs.STATS["loaded"] - before <= 8
    assert np.all(np.isfinite(sol.increments[-1].sens["R"]))


def test_bad_cache_settings_warn_once_and_land_in_the_summary(cache, monkeypatch, tmp_path):
    """A cap that is not a size, or a cache directory that cannot be written, is
    said once per process (a SignoriniWarning) and listed in summary.json; the
    run itself is unaffected."""
    from signorini.app.runner import write_summary_json
    from signorini.errors import SignoriniWarning

    monkeypatch.setattr(_programs, "WARNINGS", [])
    monkeypatch.setenv("SIGNORINI_CACHE_MAX_MB", "lots")
    with pytest.warns(SignoriniWarning, match="SIGNORINI_CACHE_MAX_MB='lots'"):
        assert _programs.max_bytes() == 2048 * 2**20
    _programs.max_bytes()  # said once
    assert len(_programs.WARNINGS) == 1
    blocked = tmp_path / "blocked"
    blocked.write_text("a file where the cache directory should be")
    monkeypatch.setenv("SIGNORINI_CACHE_DIR", str(blocked))
    monkeypatch.setenv("SIGNORINI_CACHE_MAX_MB", "64")
    with pytest.warns(SignoriniWarning, match="cannot be kept"):
        sol, counts = _solve()
    assert counts["saved"] == 0 and np.all(np.isfinite(sol.increments[-1].w))
    out = tmp_path / "out"
    out.mkdir()
    summary = write_summary_json(out, {"warnings": ["from the solve"]})
    assert summary["warnings"][0] == "from the solve" and len(summary["warnings"]) == 3
    assert any("SIGNORINI_CACHE_MAX_MB" in w for w in summary["warnings"])


def test_contact_output_reuses_the_models_fields_program(monkeypatch):
    """The contact output of a solution on a whole-mesh model takes its values from
    the model's ``fields`` program (which the increment checks compiled) and builds
    only the JVP of its sensitivities; a solution without sensitivities (a
    finite-difference re-solve) builds nothing. The values are those of the
    model's contact_fields compiled on its own."""
    from signorini._jax import jax
    from signorini.params import as_jax

    pb = hertz.hertz_problem(n_fine=8, size=8)
    sol = sg.solve(pb, wrt=["R"])
    built = []
    build = _programs.Program._build
    monkeypatch.setattr(_programs.Program, "_build",
                        lambda self, args, sig: built.append(self.name) or build(self, args, sig))
    c = sol.contact()
    assert [n for n in built if n.startswith("response:('contact'")] \
        == ["response:('contact', 0):False:jvp"], built
    built.clear()
    plain = sg.solve(pb.with_params(R=pb.params["R"] * 1.001))
    c_plain = plain.contact()
    assert built == [] and "dp_N_dR" not in c_plain
    inc = sol.increments[-1]
    ref = jax.jit(lambda w, p, t: sol.model.contact_fields(w, p, t, 0))(inc.w, as_jax(pb.params), inc.t)
    for k in ("gap", "p_N", "p_T"):
        np.testing.assert_allclose(c[k], np.asarray(ref[k]), rtol=0,
                                   atol=1e-13 * np.abs(np.asarray(ref[k])).max())
    assert np.abs(c["dp_N_dR"]).max() > 0



def test_frictionless_switch_fields_come_from_the_fields_program(monkeypatch):
    """Without a stick branch or a yield ratio, the fields that locate switch points
    (gap, p_N, no stick margin) are the contact fields: no switch_fields program is
    built for a frictionless solve, and they equal that program's."""
    from signorini.params import as_jax

    built = []
    build = _programs.Program._build
    monkeypatch.setattr(_programs.Program, "_build",
                        lambda self, args, sig: built.append(self.name) or build(self, args, sig))
    stepping._MODELS.clear()
    pb = hertz.hertz_problem(n_fine=8, size=8)
    sol = sg.solve(pb, wrt=["R"])
    assert "switch_fields" not in built and "fields" in built, built
    m, inc = sol.model, sol.increments[-1]
    p = as_jax(pb.params)
    (got,), ratio = m.compiled.switch_fields(inc.w, p, inc.t)
    (ref,), ref_ratio = m._switch_fields_whole(inc.w, p, inc.t, None)
    assert ratio is None and ref_ratio is None
    for k in ("gap", "p_N", "stick_margin"):
        np.testing.assert_array_equal(np.asarray(got[k]), np.asarray(ref[k]))
    assert np.all(np.isinf(got["stick_margin"])) and np.asarray(ref["p_N"]).max() > 0
