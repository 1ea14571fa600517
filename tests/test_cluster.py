"""One fit's per-patch work as Dask tasks (meshfit.pipeline.cluster): the same fit as on
threads, bit for bit, with or without a lost worker; the command line's flags and errors."""

from __future__ import annotations

import json
import os
import socket
import tempfile
from pathlib import Path

import numpy as np
import pytest

from meshfit import cli
from meshfit.errors import InputError
from meshfit.pipeline import ClusterOptions, FitOptions, fit
from meshfit.pipeline import cluster as cl
from meshfit.pipeline.outputs import CACHE

from .conftest import ROOT, mesh_path, real_mesh

pytestmark = pytest.mark.slow

LAYOUT = ROOT / "examples" / "layouts" / "spot.json"
#: matched map shapes (the default): most maps are finer than their spring grids, so their
#: tasks search the whole scan
MATCHED = FitOptions(controls=(4, 4), spring_level=1, formats=("obj", "exr"), report=False)
NATIVE = FitOptions(controls=(4, 4), spring_level=1, report=False, map_shapes="native")
#: files holding timings, and the manifest, which holds the summary's hash
TIMED = {"summary.json", "manifest.json"}


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        ) as lc,
        Client(lc) as c,
    ):
        yield c


@pytest.fixture(scope="module")
def on_threads(tmp_path_factory):
    out = tmp_path_factory.mktemp("threads")
    return fit(real_mesh("spot"), LAYOUT, options=MATCHED, out=out, cluster=None), out


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in TIMED
    }


def _same_fit(a, b) -> None:
    """Spring grids, splines, maps and errors the same bits; the summaries' patch rows the
    same but for their timings."""
    assert len(a.patches) == len(b.patches)
    for pa, pb in zip(a.patches, b.patches, strict=True):
        assert np.array_equal(pa.spring, pb.spring)
        assert np.array_equal(pa.surface.control_points, pb.surface.control_points)
        assert np.array_equal(pa.displacement.values, pb.displacement.values)
    assert a.summary["errors"] == b.summary["errors"]
    assert np.array_equal(a.spline_distance, b.spline_distance)

    def untimed(rows):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]

    assert untimed(a.summary["patches"]) == untimed(b.summary["patches"])


def test_tasks_give_the_same_fit(on_threads, client, tmp_path):
    want, ref = on_threads
    ticks: list[tuple[str, int, int]] = []
    got = fit(
        real_mesh("spot"),
        LAYOUT,
        options=MATCHED,
        out=tmp_path,
        cluster=client,
        progress=lambda *t: ticks.append(t),
    )
    _same_fit(want, got)
    assert _files(tmp_path) == _files(ref)  # every file the same bytes (the stage cache too)
    stages = got.summary["stages"]
    per_patch = ("springs", "fit", "displacement", "errors")
    assert all(stages[k]["patch_tasks"] for k in per_patch)
    assert not any(want.summary["stages"][k]["patch_tasks"] for k in per_patch)
    # progress ticks once per finished task, up to every patch
    for stage in per_patch:
        done = [d for s, d, n in ticks if s == stage and n == 24]
        assert done == list(range(25)), stage
    assert not (tmp_path / CACHE / cl.SCRATCH).exists()  # the scratch folder is gone
    # the peak memory counts the workers too
    mem, alone = got.summary["memory"], want.summary["memory"]
    assert mem["peak_rss_workers"] > 0 and alone["peak_rss_workers"] is None
    assert mem["peak_rss_total"] == mem["peak_rss_process"] + mem["peak_rss_workers"]


def test_own_local_cluster_without_an_output_folder():
    """A LocalCluster of the fit's own (started and shut by the fit), maps at their spring
    grids' shapes (no scan); without ``out`` the scratch folder is a temporary one, removed
    after the fit."""
    tmp = Path(tempfile.gettempdir())
    before = set(tmp.glob("meshfit-tasks-*"))
    want = fit(real_mesh("spot"), LAYOUT, options=NATIVE, cluster=None)
    own = ClusterOptions(processes=1, memory_limit="2GiB")
    got = fit(real_mesh("spot"), LAYOUT, options=NATIVE, cluster=own)
    _same_fit(want, got)
    assert got.summary["stages"]["springs"]["patch_tasks"] is True
    assert set(tmp.glob("meshfit-tasks-*")) == before


def spring_task_losing_a_worker(path, options):
    """The spring task, which ends its worker process the first time it runs in a fit (the
    scheduler must run it again elsewhere)."""
    marker = Path(path).parent / "lost-a-worker"
    if not marker.exists():
        marker.touch()
        os._exit(1)
    return cl.spring_file_task(path, options)


def test_a_lost_worker_changes_nothing(on_threads, client, tmp_path, monkeypatch):
    want, ref = on_threads
    pids = set(client.run(os.getpid).values())
    # the task the client submits (pickled by name: the workers import this module)
    monkeypatch.setattr(cl, "spring_file_task", spring_task_losing_a_worker)
    got = fit(real_mesh("spot"), LAYOUT, options=MATCHED, out=tmp_path, cluster=client)
    assert pids - set(client.run(os.getpid).values())  # a worker was lost (and replaced)
    _same_fit(want, got)
    assert _files(tmp_path) == _files(ref)


def test_cluster_argument():
    assert cl.resolve_cluster(None, 10**9) is None
    assert cl.resolve_cluster(3, 0) == ClusterOptions(processes=3)
    assert cl.resolve_cluster("tcp://h:1", 0) == ClusterOptions(scheduler="tcp://h:1")
    assert cl.resolve_cluster("auto", 10**9) is None  # off by default (LOCAL_CLUSTER_FACES)
    for bad in (0, -1, True, 2.5, "", ClusterOptions):
        with pytest.raises(InputError, match=r"cluster must be|scheduler must be"):
            cl.resolve_cluster(bad, 0)
    with pytest.raises(InputError, match="retries"):
        ClusterOptions(retries=-1)
    with pytest.raises(InputError, match="processes"):
        ClusterOptions(processes=0)
    for bad in ("4 gigs", 0, "", None):
        with pytest.raises(InputError, match="memory_limit"):
            ClusterOptions(memory_limit=bad)
    with pytest.raises(InputError, match="not both"):
        fit(real_mesh("spot"), LAYOUT, patch_map=lambda fn, items: [], cluster=2)


def test_large_meshes_take_a_local_cluster_above_the_threshold(monkeypatch):
    monkeypatch.setattr(cl, "LOCAL_CLUSTER_FACES", 1000)
    assert cl.resolve_cluster("auto", 999) is None
    assert cl.resolve_cluster("auto", 1000) == ClusterOptions()
    assert cl.resolve_cluster(None, 1000) is None  # threads, when asked


def test_cli_flags_parse():
    parser = cli.build_parser()
    from meshfit.fit_cli import _cluster

    args = parser.parse_args(["fit", "a.ply", "--processes", "3"])
    assert (args.processes, args.scheduler, _cluster(args)) == (3, None, 3)
    args = parser.parse_args(["fit", "a.ply", "--processes", "0"])
    assert _cluster(args) is None
    args = parser.parse_args(["fit", "a.ply", "--scheduler", "tcp://h:8786", "--workers", "2"])
    assert (_cluster(args), args.workers) == ("tcp://h:8786", 2)
    assert _cluster(parser.parse_args(["fit", "a.ply"])) == "auto"
    with pytest.raises(SystemExit):  # one or the other
        parser.parse_args(["fit", "a.ply", "--processes", "2", "--scheduler", "tcp://h:1"])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_is_one_line_and_exit_code_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cl, "CONNECT_SECONDS", 1.0)
    address = f"tcp://127.0.0.1:{_free_port()}"
    out = tmp_path / "fit"
    code = cli.main(["fit", str(mesh_path("spot")), "--scheduler", address, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert f"meshfit: error: cannot reach the Dask scheduler at '{address}'" in err
    assert "Traceback" not in err
    assert not out.exists()  # refused before any work: no folder left


def test_cli_on_a_scheduler_address(on_threads, client, tmp_path, capsys):
    want, _ = on_threads
    out = tmp_path / "fit"
    argv = ["fit", str(mesh_path("spot")), "--layout", str(LAYOUT), "--cv", "4x4"]
    argv += ["--level", "1", "--formats", "obj,exr", "--no-report", "--out", str(out)]
    code = cli.main([*argv, "--scheduler", client.scheduler.address, "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["stages"]["springs"]["patch_tasks"] is True
    assert summary["errors"] == want.summary["errors"]
