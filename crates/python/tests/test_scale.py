"""Sweeps spread over processes, Dask and Ray with nothing but femp installed on the workers:
scenes and results pickle, femp.sweep.run_case is found by name, and every case's metrics are
those of the same case run here, bit for bit."""

import os
import pickle

import numpy as np
import pytest

import femp
import femp.sweep


@pytest.fixture
def cases(slope):
    scene = femp.Scene.load(slope)
    changes = femp.sweep.grid({"contact.friction": [0.0, 0.6], "time.duration": [0.05]})
    assert changes == [{"contact.friction": 0.0, "time.duration": 0.05},
                       {"contact.friction": 0.6, "time.duration": 0.05}]
    return scene, changes


def local(scene, changes, tmp_path):
    return [femp.sweep.run_case(scene, c, tmp_path / "local" / str(i))
            for i, c in enumerate(changes)]


def same(results, expected):
    assert len(results) == len(expected)
    for r, e in zip(results, expected):
        assert r.summary["status"] == "completed"
        for k, col in e.metrics.items():
            if k != "wall_s":
                np.testing.assert_array_equal(r.metrics[k], col, err_msg=k)


def test_scenes_and_results_pickle(slope, tmp_path):
    scene = femp.Scene.load(slope).with_changes({"time.duration": 0.02})
    back = pickle.loads(pickle.dumps(scene))
    assert (back.to_json(), back.base_dir, back.name) == (scene.to_json(), scene.base_dir,
                                                          scene.name)
    r = femp.sweep.run_case(back, None, tmp_path / "p")
    r2 = pickle.loads(pickle.dumps(r))
    assert r2.summary == r.summary and r2.metrics.keys() == r.metrics.keys()


def test_a_process_pool_runs_the_cases(cases, tmp_path):
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    scene, changes = cases
    # Spawned, not forked: a fork copies a process whose femp threads may hold locks.
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        results = list(pool.map(femp.sweep.run_case, [scene] * 2, changes,
                                [str(tmp_path / "pool" / str(i)) for i in range(2)]))
    same(results, local(scene, changes, tmp_path))


def test_dask_runs_the_cases(cases, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    scene, changes = cases
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        futures = client.map(femp.sweep.run_case, [scene] * 2, changes,
                             [str(tmp_path / "dask" / str(i)) for i in range(2)])
        results = client.gather(futures)
    same(results, local(scene, changes, tmp_path))


def test_ray_runs_the_cases(cases, tmp_path):
    ray = pytest.importorskip("ray")
    scene, changes = cases
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"RAYON_NUM_THREADS": "1"}})
    try:
        run = ray.remote(femp.sweep.run_case)
        results = ray.get([run.remote(scene, c, str(tmp_path / "ray" / str(i)))
                           for i, c in enumerate(changes)])
    finally:
        ray.shutdown()
    same(results, local(scene, changes, tmp_path))
    assert os.path.exists(tmp_path / "ray" / "1" / "summary.json")
