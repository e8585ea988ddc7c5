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
    """An empty cache directory for this test; every model built afresh; the
    process's cache warnings as they were before it (restored after)."""
    monkeypatch.setenv("SIGNORINI_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("SIGNORINI_PROGRAM_CACHE", raising=False)
    monkeypatch.setattr(_programs, "WARNINGS", [])
    stepping._MODELS.clear()
    yield tmp_path / "programs"
    stepping._MODELS.clear()


def _solve():
    stepping._MODELS.clear()  # a new model: its programs come from the disk or XLA
    before = dict(_programs.STATS)
    sol = sg.solve(hertz.hertz_problem(n_fine=8, size=8), steps=2, wrt=["R", "E"])
    counts = {k: _programs.STATS[k] - before.get(k, 0)
              for k in ("compiled", "loaded", "rebuilt", "ignored", "saved", "evicted")}
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


def test_three_dimensional_models_are_known_by_content():
    """A 3-D problem of hexahedra, of tetrahedra or of both has a content digest
    (its programs are kept between processes), the same for the same problem built
    twice and another for another cell kind."""
    from signorini.fem.mesh import merge
    from signorini.fem.mesh3d import box, tetrahedra
    from signorini.model.identity import stable_digest, structure_key

    def problem(kind):
        b = box(np.linspace(0, 1, 3), np.linspace(0, 1, 3), np.linspace(0, 1, 3))
        mesh = {"hex": b, "tet": tetrahedra(b),
                "mixed": merge({"low": b, "up": tetrahedra(box(*[np.linspace(0, 1, 3)] * 2,
                                                               np.linspace(1, 2, 3)))})}[kind]
        return sg.Problem(mesh, sg.LinearElastic(E="E"), {"E": 1.0, "nu": 0.3},
                          fixed=[sg.Fixed("z0" if kind != "mixed" else "low.z0", k) for k in range(3)])

    digests = {k: stable_digest(structure_key(problem(k))) for k in ("hex", "tet", "mixed")}
    assert None not in digests.values() and len(set(digests.values())) == 3
    assert digests["hex"] == stable_digest(structure_key(problem("hex")))


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


# ------------------------------------------------ damaged and untrusted entries
def _solve_said(cache_dir):
    """_solve, with the warnings that name a directory of the cache (any category:
    JAX's own UserWarnings too)."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol, counts = _solve()
    said = [w for w in caught if str(cache_dir.parent) in str(w.message)]
    return sol, counts, said


def _only_cache_warning(said, fragment):
    """The one warning said about the cache: a SignoriniWarning with ``fragment``,
    the same text in _programs.WARNINGS (and so in summary.json)."""
    from signorini.errors import SignoriniWarning

    assert len(said) == 1, [str(w.message) for w in said]
    assert said[0].category is SignoriniWarning
    msg = str(said[0].message)
    assert fragment in msg, msg
    assert _programs.WARNINGS == [msg]
    return msg


def test_damaged_entries_are_one_warning_in_the_summary(cache, tmp_path):
    """Entries damaged in every way (truncated, overwritten with junk, emptied) are
    rebuilt, as before, and said once, as a SignoriniWarning naming the cache
    directory and what was done, which summary.json lists; then the rebuilt
    entries load without a word."""
    from signorini.app.runner import write_summary_json

    first, c1 = _solve()
    files = sorted(cache.glob("*.bin"))
    for k, f in enumerate(files):
        f.write_bytes([f.read_bytes()[:200], b"junk\n" * 3, b""][k % 3])
    again, c2, said = _solve_said(cache)
    assert c2["rebuilt"] == len(files) and c2["loaded"] == 0 and c2["saved"] == len(files)
    _same(first, again)
    msg = _only_cache_warning(said, f"the compilation cache {cache} had damaged entries (the first: ")
    assert "they were ignored, compiled again and replaced, and the results are unaffected" in msg
    out = tmp_path / "out"
    out.mkdir()
    summary = write_summary_json(out, {"warnings": ["from the solve"]})
    assert summary["warnings"] == ["from the solve", msg]
    _programs.WARNINGS.clear()
    _, c3, said = _solve_said(cache)
    assert c3["loaded"] == c1["compiled"] and c3["compiled"] == 0 and not said


@pytest.mark.parametrize("how", ["group-writable", "others-writable", "another owner", "symlink"])
def test_entries_not_your_own_are_not_loaded(cache, tmp_path, how):
    """An entry that someone else owns or can write (or a symbolic link) is a program
    someone else could have put there: not loaded, compiled again and replaced by
    a private entry of the user's own; said once, in the summary."""
    _, c1 = _solve()
    files = sorted(cache.glob("*.bin"))
    for f in files:
        if how == "group-writable":
            f.chmod(0o660)
        elif how == "others-writable":
            f.chmod(0o606)
        elif how == "another owner":
            if os.geteuid() != 0:
                pytest.skip("giving a file to another user needs root")
            os.chown(f, os.getuid() + 1000, -1)
        else:
            target = tmp_path / "elsewhere" / f.name
            target.parent.mkdir(exist_ok=True)
            f.rename(target)
            f.symlink_to(target)
    _, c2, said = _solve_said(cache)
    assert c2["ignored"] == len(files) and c2["loaded"] == 0 and c2["compiled"] == c1["compiled"]
    why = {"group-writable": "writable by other users (mode 0660)",
           "others-writable": "writable by other users (mode 0606)",
           "another owner": f"owned by another user (uid {os.getuid() + 1000}; this process runs as "
                            f"uid {os.getuid()})",
           "symlink": "symbolic links"}[how]
    _only_cache_warning(said, f"the compilation cache {cache} holds entries that are {why} (the "
                              "first: ")
    for f in files:  # replaced: regular files of the user's own that only they can write
        st = os.lstat(f)
        assert st.st_uid == os.getuid() and oct(st.st_mode) == oct(0o100600), (f, oct(st.st_mode))
    _, c3, said = _solve_said(cache)
    assert c3["loaded"] == c1["compiled"] and c3["ignored"] == 0 and not said


@pytest.mark.parametrize("where, mode", [("programs", 0o777), ("programs", 0o720), ("root", 0o707),
                                         ("owner", None)])
def test_a_cache_directory_others_can_write_is_not_used(cache, monkeypatch, capsys, where, mode):
    """A cache directory (SIGNORINI_CACHE_DIR or its programs/) that another user can
    write or owns: nothing is loaded from it or written to it; said once, with what
    to do; `signorini cache` shows it as not used."""
    from signorini.app.cli import main

    _, c1 = _solve()
    root = cache.parent
    if where == "owner":  # the process runs as another user than the one who made the cache
        uid = os.getuid()
        monkeypatch.setattr(os, "getuid", lambda: uid + 1000)
        bad, why = root, f"owned by another user (uid {uid}; this process runs as uid {uid + 1000})"
    else:
        bad = cache if where == "programs" else root
        bad.chmod(mode)
        why = f"writable by other users (mode {mode:04o})"
    before = {f: f.stat().st_mtime_ns for f in cache.glob("*.bin")}
    _, c2, said = _solve_said(cache)
    assert c2["loaded"] == 0 and c2["saved"] == 0 and c2["rebuilt"] == c2["ignored"] == 0
    assert c2["compiled"] == c1["compiled"]
    assert {f: f.stat().st_mtime_ns for f in cache.glob("*.bin")} == before  # nothing written
    mine = [w for w in said if f"the compilation cache {bad} is " in str(w.message)]
    assert len(mine) == 1, [str(w.message) for w in said]
    msg = str(mine[0].message)
    assert f"the compilation cache {bad} is {why}; a cache of compiled programs is code that " \
           "runs, so nothing is loaded from it or kept in it" in msg, msg
    assert (f"chmod go-w {bad}" in msg) == (where != "owner") and msg in _programs.WARNINGS
    capsys.readouterr()
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert f"signorini programs: {cache}: {len(before)} file(s)" in out
    assert f"MB (not used: {bad} is {why})" in out.splitlines()[0], out
    if where != "owner":
        bad.chmod(0o700)


def test_a_jax_directory_others_can_write_is_said_and_programs_still_load(cache):
    """JAX's part of the cache (jax/) writable by others is said (JAX's cache is not
    set up there), and signorini's own programs, in a private directory, still load."""
    _, c1 = _solve()
    jax_dir = cache.parent / "jax"
    jax_dir.mkdir(exist_ok=True)
    jax_dir.chmod(0o777)
    _, c2, said = _solve_said(cache)
    assert c2["loaded"] == c1["compiled"] and c2["compiled"] == 0
    _only_cache_warning(said, f"the compilation cache {jax_dir} is writable by other users "
                              "(mode 0777)")
    assert _programs.directory_problem(cache) is None


JAX_SCRIPT = textwrap.dedent("""
    import json, os, sys, warnings
    os.umask(0o002)  # a umask that leaves new files group-writable: the entries are made private
    warnings.simplefilter("always")
    import signorini
    from signorini import _programs
    from signorini._jax import jax, jnp
    hits = []
    jax.monitoring.register_event_listener(
        lambda event, **_: hits.append(event) if event == "/jax/compilation_cache/cache_hits" else None)
    value = jax.jit(lambda x: jnp.sin(x) * jnp.cos(x) + 2.0)(0.5)
    print(json.dumps({"value": float(value), "hits": len(hits), "warnings": _programs.WARNINGS,
                      "stats": dict(_programs.STATS)}))
""")


def test_jax_compilation_cache_entries_damaged_or_not_private(tmp_path):
    """JAX's compilation cache (jax/) in fresh processes: its entries are private
    whatever the umask; a damaged entry is not JAX's UserWarning on the console
    but one SignoriniWarning naming the directory, kept in _programs.WARNINGS, and
    the entry is written again; an entry others can write is not loaded, but
    replaced; a sound private entry is loaded."""
    import json

    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(tmp_path)}
    jax_dir = tmp_path / "jax"

    def run():
        r = subprocess.run([sys.executable, "-c", JAX_SCRIPT], env=env, capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
        assert "UserWarning" not in r.stderr and "Error reading" not in r.stderr, r.stderr
        return json.loads(r.stdout.strip().splitlines()[-1])

    first = run()
    entries = sorted(jax_dir.glob("*-cache"))
    assert entries and first["hits"] == 0 and first["warnings"] == []
    assert all(os.stat(e).st_mode & 0o077 == 0 for e in entries), [oct(os.stat(e).st_mode) for e in entries]
    for e in entries:
        e.write_bytes(b"junk")
    damaged = run()
    assert damaged["value"] == first["value"] and damaged["hits"] == 0
    assert damaged["stats"].get("jax_rebuilt") == len(entries)
    [msg] = damaged["warnings"]
    assert msg.startswith(f"the compilation cache {jax_dir} had damaged entries (the first: "), msg
    assert "they were ignored, compiled again and replaced" in msg
    assert all(e.stat().st_size > 4 for e in entries)  # written again
    for e in entries:
        e.chmod(0o666)
    untrusted = run()
    assert untrusted["hits"] == 0 and untrusted["stats"].get("jax_ignored") == len(entries)
    [msg] = untrusted["warnings"]
    assert msg.startswith(f"the compilation cache {jax_dir} holds entries that are writable by "
                          "other users (mode 0666)"), msg
    assert all(os.stat(e).st_mode & 0o077 == 0 for e in entries)
    sound = run()
    assert sound["hits"] >= 1 and sound["warnings"] == [] and sound["value"] == first["value"]


LAPACK_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    from signorini import _programs
    from signorini._jax import jnp
    prog = _programs.Program(lambda a: jnp.linalg.det(a) + jnp.linalg.inv(a).sum(), "lapack-first",
                             "test-lapack-first")
    value = prog(np.array([[2.0, 1.0], [1.0, 3.0]]))
    sys.stdout.write(f"{float(value)!r} {_programs.STATS['loaded']}")
""")


def test_a_kept_program_calling_lapack_loads_first_in_a_process(tmp_path):
    """A program that calls LAPACK (a determinant, an inverse), loaded from the
    disk as the first such program of a fresh process, runs (without the
    kernels' registration that JAX does on lowering, it crashed the process)."""
    env = {**os.environ, "SIGNORINI_CACHE_DIR": str(tmp_path)}
    env.pop("SIGNORINI_PROGRAM_CACHE", None)
    runs = [subprocess.run([sys.executable, "-c", LAPACK_SCRIPT], env=env, capture_output=True,
                           text=True, timeout=300) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[-1].stderr[-2000:]
    (v0, loaded0), (v1, loaded1) = (r.stdout.split() for r in runs)
    assert (loaded0, loaded1) == ("0", "1") and float(v0) == float(v1) == pytest.approx(5.6, rel=1e-14)


def test_kept_models_are_let_go_before_the_process_runs_out_of_memory_mappings(monkeypatch):
    """Every executable's code sits in memory mappings of its own (a few hundred for
    a 3-D contact model's larger programs) and past ``vm.max_map_count`` XLA dies in
    a segmentation fault: the models kept for reuse are let go (their executables
    freed at once) when the mappings pass half the limit, when a model is built
    and while its programs are built; the model in use stays."""
    import gc
    import weakref

    maps = _programs.code_maps()
    if maps is None:
        pytest.skip("the system does not say how many memory mappings a process has")
    assert 0 < maps[0] < maps[1]
    monkeypatch.setattr(stepping, "_MODELS", stepping.OrderedDict())
    pressed = [False]
    real = _programs.code_maps
    monkeypatch.setattr(_programs, "code_maps",
                        lambda: (maps[1], maps[1]) if pressed[0] else real())

    def solved(n_fine):
        pb = hertz.hertz_problem(n_fine=n_fine, size=8)
        sg.solve(pb, steps=1)
        return stepping.model_for(pb)

    first, second = solved(6), solved(8)
    assert len(stepping._MODELS) == 2  # no pressure: both kept
    gone = weakref.ref(first)
    del first
    pressed[0] = True  # a third model, the mappings at the limit: the older two go
    third = solved(10)
    gc.collect()
    assert list(stepping._MODELS.values()) == [third]
    assert gone() is None  # and its executables with it
    # a program built while the mappings are at the limit lets go of every model
    # but the one used last
    pressed[0] = False
    stepping._MODELS[object()] = second
    stepping._MODELS.move_to_end(next(k for k, m in stepping._MODELS.items() if m is third))
    pressed[0] = True
    monkeypatch.setattr(_programs, "CHECK_EVERY", 1)
    sg.solve(hertz.hertz_problem(n_fine=10, size=8), steps=1, wrt=["R"])  # builds the DDM's programs
    assert list(stepping._MODELS.values()) == [third]
