"""jaxhand batch: manifests, the in-process job runner, the report, and a 2-worker local cluster."""

import json
import os

import numpy as np
import pytest

from jaxhand import InputError
from jaxhand.batch import finished_summary, load_manifest, parse_manifest, run_batch, run_job
from jaxhand.cli import main

# -- manifests -----------------------------------------------------------------------------------


def test_toml_defaults_apply_and_job_keys_override():
    m = parse_manifest("""
format_version = 1
[defaults]
no_video = true
steps = 10
camera = ["a.json", "b.json"]
[[jobs]]
name = "one"
inputs = ["left", "right"]
[[jobs]]
name = "two"
inputs = "seq"
steps = 3
no_video = false
max-frames = 4
""", "jobs.toml")
    one, two = m.jobs
    assert one.args == ("track", "left", "right", "--no-video", "--steps", "10", "--camera", "a.json", "--camera",
                        "b.json")
    assert two.args == ("track", "seq", "--steps", "3", "--camera", "a.json", "--camera", "b.json",
                        "--max-frames", "4")
    assert two.argv("out") == [*two.args, "--out", os.path.join("out", "two")]


def test_csv_defaults_row_empty_cells_and_lists():
    m = parse_manifest("name,command,inputs,model,camera,no_video,max_frames\n"
                       "# a comment line\n"
                       "*,track,,hand21,cam.json,yes,\n"
                       "a,,v1.mp4,,,,5\n"
                       "b,track,x;y,index_thumb,c1.json;c2.json,no,\n", "jobs.csv")
    a, b = m.jobs
    assert a.args == ("track", "v1.mp4", "--model", "hand21", "--camera", "cam.json", "--no-video",
                      "--max-frames", "5")
    assert b.args == ("track", "x", "y", "--model", "index_thumb", "--camera", "c1.json", "--camera", "c2.json")
    assert a.where == "line 4" and b.where == "line 5"


@pytest.mark.parametrize("text, path, match", [
    ("[[jobs]]\nname='a'\ninputs='x'\nmax_frame=3\n", "m.toml",
     r"m.toml: \[\[jobs\]\] #1 \(job 'a'\), column 'max_frame': not an option of 'jaxhand track' "
     r"\(did you mean 'max-frames'\?\)"),
    ("[[jobs]]\nname='a'\ninputs='x'\n[[jobs]]\nname='a'\ninputs='y'\n", "m.toml",
     r"#2, column 'name': job name 'a' is already used at \[\[jobs\]\] #1"),
    ("[[jobs]]\nname='../a'\ninputs='x'\n", "m.toml", r"column 'name': '../a' cannot name a folder"),
    ("[[jobs]]\nname='a'\ninputs='x'\nout='o'\n", "m.toml", r"column 'out': set by jaxhand batch"),
    ("[[jobs]]\nname='a'\ncommand='trak'\ninputs='x'\n", "m.toml",
     r"column 'command': expected one of track, fit-landmarks, got 'trak' \(did you mean 'track'\?\)"),
    ("[[jobs]]\nname='a'\ninputs='x'\nsteps='many'\n", "m.toml",
     r"\(job 'a'\): argument --steps: invalid int value: 'many'"),
    ("[[jobs]]\nname='a'\ninputs='x'\nno_video='maybe'\n", "m.toml", r"column 'no_video': expected true or false"),
    ("[[jobs]]\nname='a'\n", "m.toml", r"\(job 'a'\): missing column 'inputs'"),
    ("[defaults]\nstep=3\n[[jobs]]\nname='a'\ninputs='x'\n", "m.toml",
     r"defaults, column 'step': not an option of any job's command \(did you mean 'steps'\?\)"),
    ("[default]\n", "m.toml", r"unknown top-level key 'default' \(did you mean 'defaults'\?\)"),
    ("format_version = 2\n[[jobs]]\nname='a'\ninputs='x'\n", "m.toml", r"format_version: expected 1, got 2"),
    ("[[jobs]\n", "m.toml", r"m.toml: not valid TOML"),
    ("", "m.toml", r"m.toml: no jobs"),
    ("name,inputs\na,x,extra\n", "m.csv", r"m.csv: line 2: 3 cells but the header has 2 columns"),
    ("name,inputs\na,x\n*,y\n", "m.csv", r"line 3: the defaults row \(name '\*'\) must be the first"),
    ("name,inputs,name\n", "m.csv", r"column 'name' appears twice"),
    ("inputs\nx\n", "m.csv", r"m.csv: line 2, column 'name': missing"),
    ("name,inputs\n", "m.yaml", r"expected a .csv or .toml manifest, got '.yaml'"),
])
def test_manifest_errors_are_one_line_naming_row_and_column(text, path, match):
    with pytest.raises(InputError, match=match) as info:
        parse_manifest(text, path)
    assert "\n" not in str(info.value)


def test_fit_landmarks_is_accepted_only_where_the_command_exists():
    from jaxhand.batch._manifest import _command_parsers

    text = "[[jobs]]\nname='a'\ncommand='fit-landmarks'\ninputs='lm.csv'\nmodel='hand21'\ncamera='cam.json'\n"
    if "fit-landmarks" in _command_parsers():
        assert parse_manifest(text, "m.toml").jobs[0].args[:2] == ("fit-landmarks", "lm.csv")
    else:
        with pytest.raises(InputError, match="'fit-landmarks' is not available in this jaxhand"):
            parse_manifest(text, "m.toml")


def test_defaults_apply_where_the_command_has_the_option_and_inputs_fills_its_positional(monkeypatch):
    """With a stand-in ``fit-landmarks`` parser (LANDMARKS, --model, --camera, --out), as on the
    landmark branch: a track-only default stays out of its jobs, and ``inputs`` names LANDMARKS."""
    import argparse

    import jaxhand.batch._manifest as manifest

    real = manifest._command_parsers

    def parsers():
        fit = argparse.ArgumentParser(prog="jaxhand fit-landmarks")
        fit.add_argument("landmarks", metavar="LANDMARKS")
        fit.add_argument("--model")
        fit.add_argument("--camera", action="append")
        fit.add_argument("--out", required=True)
        return {**real(), "fit-landmarks": fit}

    monkeypatch.setattr(manifest, "_command_parsers", parsers)
    m = parse_manifest("name,command,inputs,model,steps\n*,,,hand21,5\nt,track,seq,,\nf,fit-landmarks,lm.json,,\n",
                       "m.csv")
    assert [j.args for j in m.jobs] == [("track", "seq", "--model", "hand21", "--steps", "5"),
                                        ("fit-landmarks", "lm.json", "--model", "hand21")]
    with pytest.raises(InputError, match=r"line 2 \(job 'f'\), column 'steps': not an option of 'jaxhand "
                                         r"fit-landmarks'"):
        parse_manifest("name,command,landmarks,steps\nf,fit-landmarks,lm.json,5\n", "m.csv")


def test_the_cli_reports_a_bad_manifest_in_one_line_before_starting(tmp_path, capsys):
    path = tmp_path / "jobs.toml"
    path.write_text("[[jobs]]\nname='a'\ninputs='x'\nmodl='hand21'\n")
    assert main(["batch", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jaxhand batch: error: ") and "did you mean 'model'?" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


# -- jobs in this process --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sequences(tmp_path_factory):
    """Three short rendered sequences of one model (so one compiled step serves them all)."""
    from jaxhand.render import RenderConfig, make_preset, write_sequence

    root = tmp_path_factory.mktemp("batch_seqs")
    paths = []
    for i, noise in enumerate((0.0, 4.0, 8.0)):
        seq = make_preset("two_finger_occlusion", frames=6, size=(160, 120))
        write_sequence(seq, root / f"s{i}", RenderConfig(noise_sigma=noise, seed=i), progress=False)
        paths.append(root / f"s{i}")
    return paths


@pytest.mark.slow
def test_run_job_matches_the_single_command_and_compiles_once_per_structure(sequences, tmp_path, capsys):
    assert main(["track", str(sequences[1]), "--out", str(tmp_path / "ref"), "--no-video"]) == 0
    capsys.readouterr()
    first = run_job("a", ["track", str(sequences[0]), "--no-video", "--out", str(tmp_path / "a")], tmp_path / "a")
    second = run_job("b", ["track", str(sequences[1]), "--no-video", "--out", str(tmp_path / "b")], tmp_path / "b")
    assert first["status"] == second["status"] == "done" and first["error"] is None
    # The step of this structure was compiled by the reference run above: nothing compiles again.
    assert second["jit_compiles"] == 0
    assert second["summary"]["frames"] == 6 and finished_summary(tmp_path / "b")["frames"] == 6
    _assert_same_outputs(tmp_path / "b", tmp_path / "ref")
    assert (tmp_path / "b" / "batch.log").read_text().startswith(f"$ jaxhand track {sequences[1]}")
    assert capsys.readouterr().out == ""       # the job's printing went into its batch.log


def test_run_job_records_a_failure_without_raising(tmp_path):
    rec = run_job("x", ["track", str(tmp_path / "missing"), "--out", str(tmp_path / "x")], tmp_path / "x")
    assert rec["status"] == "failed" and rec["exit_code"] == 2 and rec["summary"] is None
    assert rec["error"] == ("jaxhand track: error: --model is required unless INPUT is a 'jaxhand synth' or a "
                            "dev-set folder")
    saved = json.loads((tmp_path / "x" / "error.json").read_text())
    assert saved["error"] == rec["error"] and saved["argv"][-2:] == ["--out", str(tmp_path / "x")]
    rec = run_job("y", ["track", "--steps", "x"], tmp_path / "y")     # an argparse error exits
    assert rec["status"] == "failed" and rec["exit_code"] == 2 and "invalid int value: 'x'" in rec["error"]


def test_finished_summary_needs_complete_json(tmp_path):
    (tmp_path / "summary.json").write_text('{"frames": 3, "wall_s"')      # cut short mid-write
    assert finished_summary(tmp_path) is None
    (tmp_path / "summary.json").write_text('{"frames": 3}\n')
    assert finished_summary(tmp_path) == {"frames": 3}
    assert finished_summary(tmp_path / "nowhere") is None


def test_an_interrupted_batch_writes_its_summary_and_says_how_to_resume(tmp_path, monkeypatch, capsys):
    import jaxhand.batch._runner as runner

    path = tmp_path / "jobs.toml"
    path.write_text("[[jobs]]\nname='a'\ninputs='x'\n[[jobs]]\nname='b'\ninputs='y'\n[[jobs]]\nname='c'\ninputs='z'\n")

    def interrupted(todo, out, workers, scheduler, records, show, log):
        records["a"] = {"name": "a", "status": "done", "summary": {"frames": 5, "frames_per_second_end_to_end": 2.0}}
        (out / "b").mkdir()
        (out / "b" / "angles.csv").write_text("frame,time_s\n0,0.0\n")     # b was cut short
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "_run_jobs", interrupted)
    assert main(["batch", str(path), "--out", str(tmp_path / "out")]) == 130
    assert "interrupted; 1 of 3 jobs finished, 1 cut short" in capsys.readouterr().err
    report = json.loads((tmp_path / "out" / "batch_summary.json").read_text())
    assert [(r["name"], r["status"], r["frames"]) for r in report["jobs"]] == [
        ("a", "done", 5), ("b", "interrupted", None), ("c", "not run", None)]
    assert report["totals"] == {"done": 1, "skipped": 0, "failed": 0, "interrupted": 1, "not run": 1}


def _assert_same_outputs(out, ref):
    assert (out / "angles.csv").read_bytes() == (ref / "angles.csv").read_bytes()
    with np.load(out / "results.npz") as a, np.load(ref / "results.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key, strict=True)


# -- a local cluster ------------------------------------------------------------------------------


def _single_commands(argvs):
    """The single commands, each through ``jaxhand.cli.main``, in one fresh process pinned like a
    batch worker (jaxhand.batch.pinned_environment, which keeps the caller's XLA flags):
    single-threaded Eigen rounds differently from the multi-threaded default in the last bits, so
    bit-equality holds under equal settings."""
    import subprocess
    import sys

    from jaxhand.batch import pinned_environment

    code = "import sys, json\nfrom jaxhand.cli import main\nsys.exit(max(main(a) for a in json.loads(sys.argv[1])))"
    with pinned_environment():
        env = dict(os.environ)
    subprocess.run([sys.executable, "-c", code, json.dumps(argvs)], env=env, check=True, capture_output=True)


@pytest.mark.slow
def test_batch_on_two_workers_equals_single_commands_and_resumes(sequences, tmp_path, capsys):
    refs = [tmp_path / f"ref{i}" for i in range(len(sequences))]
    _single_commands([["track", str(seq), "--out", str(ref), "--no-video"] for seq, ref in zip(sequences, refs)])
    manifest = tmp_path / "jobs.csv"
    manifest.write_text("name,inputs,no_video\n*,,true\n"
                        + "".join(f"j{i},{seq}\n" for i, seq in enumerate(sequences)) + f"bad,{tmp_path / 'no'}\n")
    out = tmp_path / "batch"
    rows = run_batch(load_manifest(manifest), out, workers=2, progress=True)
    assert [(r["name"], r["status"]) for r in rows] == [("j0", "done"), ("j1", "done"), ("j2", "done"),
                                                        ("bad", "failed")]
    assert "--model is required" in rows[3]["error"] and (out / "bad" / "error.json").exists()
    for i in range(3):
        _assert_same_outputs(out / f"j{i}", refs[i])
        assert rows[i]["frames"] == 6 and rows[i]["frames_per_second"] > 0
        assert rows[i]["joint_error_deg_mean"] == json.loads((refs[i] / "summary.json").read_text())[
            "accuracy_filtered"]["joint_error_deg"]["mean"]
    # Both workers ran jobs; a worker compiles the step of this structure for its first job only.
    assert len({r["worker"] for r in rows}) == 2
    assert sum(r["jit_compiles"] == 0 for r in rows[:3]) >= 1 and sum(r["jit_compiles"] > 0 for r in rows[:3]) >= 1
    csv_rows = (out / "batch_summary.csv").read_text().splitlines()
    assert csv_rows[0].startswith("name,command,status,frames,frames_per_second,") and len(csv_rows) == 5
    assert (out / "batch_summary.png").stat().st_size > 0
    # A rerun skips the finished jobs untouched and tries the failed one again, here on a running
    # cluster given by its address.
    from distributed import LocalCluster

    stamps = {i: (out / f"j{i}" / "summary.json").stat().st_mtime_ns for i in range(3)}
    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None,
                      scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"}) as cluster:
        rows = run_batch(load_manifest(manifest), out, scheduler=cluster.scheduler_address, progress=False)
    assert [r["status"] for r in rows] == ["skipped", "skipped", "skipped", "failed"]
    assert {i: (out / f"j{i}" / "summary.json").stat().st_mtime_ns for i in range(3)} == stamps
    assert rows[3]["worker"] is not None and rows[0]["frames"] == 6
    err = capsys.readouterr().err
    assert "3 of 4 jobs finished earlier, skipped" in err
    assert f"1 job(s) on 1 worker(s) at {cluster.scheduler_address}" in err
    assert "jobs: 100%" in err          # the progress bar of the first run
