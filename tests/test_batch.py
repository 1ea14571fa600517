"""Batch fits on a dask.distributed LocalCluster: failures alone, skips, killed workers."""

from __future__ import annotations

import json
import os
import shutil
import signal
import threading
import time

import pytest

from meshfit import cli
from meshfit.batch import run_batch
from meshfit.pipeline import FitOptions

from .conftest import ROOT, mesh_path

pytestmark = pytest.mark.slow

LAYOUT = str(ROOT / "examples" / "layouts" / "spot.json")
OPTIONS = FitOptions(controls=(4, 4), spring_level=1, formats=("obj", "exr"), report=False)
#: files that hold timings, and the manifest, which holds the summary's hash (everything else
#: must be the same bytes in every run)
TIMED = {"summary.json", "done.json", "manifest.json"}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scans")
    shutil.copy(mesh_path("spot"), folder / "cow_a.ply")
    shutil.copy(mesh_path("spot"), folder / "cow_b.ply")
    (folder / "broken.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1\n")
    return folder


@pytest.fixture(scope="module")
def cluster():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address="127.0.0.1:0"
        ) as lc,
        Client(lc) as client,
    ):
        yield client


def _files(folder):
    """Every file's bytes by its name, the deliverables' stem (the mesh's name) taken out of
    both (the OBJ's material names the map files)."""
    stem = folder.name
    return {
        str(p.relative_to(folder)).replace(stem, "<stem>"): p.read_bytes().replace(
            stem.encode(), b"<stem>"
        )
        for p in sorted(folder.rglob("*"))
        # (the exports' cache record holds the hashes of files that name the stem)
        if p.is_file() and p.name not in TIMED and not p.name.startswith("exports-")
    }


@pytest.fixture(scope="module")
def undisturbed(inputs, cluster, tmp_path_factory):
    out = tmp_path_factory.mktemp("batch")
    summary = run_batch(
        str(inputs / "*.ply"), out, layout=LAYOUT, options=OPTIONS, client=cluster, quiet=True
    )
    return out, summary


def test_malformed_mesh_fails_alone(undisturbed):
    out, summary = undisturbed
    assert (summary["meshes"], summary["done"], summary["failed"]) == (3, 2, 1)
    res = summary["results"]
    assert res["broken.ply"]["status"] == "failed"
    assert "broken.ply" in res["broken.ply"]["error"]
    for name in ("cow_a.ply", "cow_b.ply"):
        assert res[name]["status"] == "done"
        assert res[name]["patches"] == 24
        assert (out / name[:-4] / f"{name[:-4]}.obj").is_file()
    assert json.loads((out / "batch.json").read_text()) == summary
    # the two copies of one mesh give the same bytes
    a, b = _files(out / "cow_a"), _files(out / "cow_b")
    assert a == b


def test_rerun_skips_finished_meshes(undisturbed, inputs, cluster):
    out, _ = undisturbed
    again = run_batch(
        str(inputs / "*.ply"), out, layout=LAYOUT, options=OPTIONS, client=cluster, quiet=True
    )
    assert again["skipped"] == 2 and again["failed"] == 1 and again["done"] == 0


def test_killed_worker_gives_the_same_outputs(undisturbed, inputs, cluster, tmp_path):
    ref, _ = undisturbed
    out = tmp_path / "killed"
    box: dict = {}
    files = [str(inputs / "cow_a.ply"), str(inputs / "cow_b.ply")]
    thread = threading.Thread(
        target=lambda: box.update(
            summary=run_batch(
                files, out, layout=LAYOUT, options=OPTIONS, client=cluster, quiet=True
            )
        )
    )
    thread.start()
    # kill a worker once a mesh is under way (its cut is written)
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and time.monotonic() < deadline and thread.is_alive():
        if list(out.glob("*/.meshfit/cut-*.npz")):
            busy = [w for w, tasks in cluster.processing().items() if tasks]
            if busy:
                pid = cluster.run(os.getpid, workers=busy[:1])[busy[0]]
                os.kill(pid, signal.SIGKILL)
                killed = pid
        time.sleep(0.05)
    thread.join(timeout=240)
    assert killed is not None, "no worker was busy to be killed"
    summary = box["summary"]
    assert summary["done"] == 2 and summary["failed"] == 0
    for stem in ("cow_a", "cow_b"):
        assert _files(out / stem) == _files(ref / stem)


def test_per_patch_tasks_give_the_same_outputs(undisturbed, inputs, cluster, tmp_path):
    ref, _ = undisturbed
    out = tmp_path / "patch_tasks"
    summary = run_batch(
        [str(inputs / "cow_a.ply")],
        out,
        layout=LAYOUT,
        options=OPTIONS,
        client=cluster,
        quiet=True,
        patch_tasks_above=1,
    )
    assert summary["done"] == 1
    fit = json.loads((out / "cow_a" / "summary.json").read_text())
    assert fit["stages"]["springs"]["patch_tasks"] is True
    assert _files(out / "cow_a") == _files(ref / "cow_a")


def test_cli_batch_on_a_scheduler_address(inputs, cluster, tmp_path, capsys):
    code = cli.main(
        [
            "batch",
            "--scheduler",
            cluster.scheduler.address,
            str(inputs / "cow_a.ply"),
            "--out",
            str(tmp_path),
            "--layout",
            LAYOUT,
            "--cv",
            "4x4",
            "--level",
            "0",
            "--formats",
            "obj",
            "--no-report",
            "--json",
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["done"] == 1


def test_task_keys_name_the_output_folder(tmp_path):
    # a scheduler that still holds a finished task returns its result for the same key: the
    # same mesh and options written elsewhere must be a new task
    from meshfit.batch import _task_key

    mesh = tmp_path / "cow.ply"
    a = _task_key(mesh, tmp_path / "one" / "cow", "k", None)
    assert a == _task_key(mesh, tmp_path / "one" / "cow", "k", None)
    assert a != _task_key(mesh, tmp_path / "two" / "cow", "k", None)
    assert a != _task_key(mesh, tmp_path / "one" / "cow", "k", 1)
    assert a != _task_key(mesh, tmp_path / "one" / "cow", "other", None)
    assert a.startswith("meshfit-fit-cow-")


def test_a_glob_takes_only_mesh_files_and_names_colliding_stems(tmp_path):
    """A glob over a folder of other files finds no mesh (nothing is written); two meshes
    whose outputs would share a folder are both named."""
    (tmp_path / "notes.txt").write_text("not a mesh")
    (tmp_path / "sub.ply").mkdir()  # a folder with a mesh suffix is not a mesh file
    with pytest.raises(Exception, match=r"no mesh file \(\.ply.*matches"):
        run_batch(str(tmp_path / "*"), tmp_path / "out", quiet=True)
    shutil.copy(mesh_path("spot"), tmp_path / "spot.ply")
    shutil.copy(mesh_path("spot"), tmp_path / "spot.obj")
    with pytest.raises(Exception, match=r"spot\.obj and .*spot\.ply have the same file name"):
        run_batch(str(tmp_path / "*"), tmp_path / "out", quiet=True)
    assert not (tmp_path / "out").exists()
