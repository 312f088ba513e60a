"""A minimal ``ident run`` result.json for report and verdict tests (no run needed)."""

from __future__ import annotations

from typing import Any


def minimal_run_data(estimates: dict[str, Any], failures: dict[str, str]) -> dict[str, Any]:
    """A run result.json with one stage, one base parameter m1 (true value 1) and one elite."""
    return {
        "format": "ident-run/1",
        "status": "complete",
        "message": "run complete",
        "name": "t",
        "seed": 1,
        "config": {
            "robot": "r.yaml",
            "stage": "wrist",
            "excitation": {"family": "joint_fourier", "criterion": "paper", "n_samples": 10},
            "elites": {"n_particles": 2, "n_elites": 1},
            "emupso": {"n_runs": 1, "n_particles": 2, "maxiter": 1, "stagnation": 1},
            "measurement": {"torque_noise_std": 0.0, "encoder_counts_per_rev": None},
            "estimation": {"methods": ["ols"]},
        },
        "robot": {"name": "r", "joint_names": ["a"], "q_limits": [[-1, 1]], "dq_limits": [1]},
        "excitation": {"variable_names": ["v"], "moving_joints": [0]},
        "warnings": [],
        "stage": {
            "name": "wrist",
            "torque_rows": [0],
            "base_method": "qr",
            "known_bodies": "all bodies are unknown in this stage",
            "counts": {"independent": 1, "dependent": 0, "unidentifiable": 0, "n_base": 1},
            "paper_counts": {"independent": 15, "dependent": 7, "unidentifiable": 8},
            "independent": ["m1"],
            "dependent": [],
            "unidentifiable": [],
            "base_names": ["m1"],
            "base_expressions": ["m1"],
            "true_base": [1.0],
            "identifiable_alone": [True],
        },
        "initial_elites": {"x": [[0.0]], "message": "1 elites found"},
        "optimization": {"n_runs_finished": 1, "runs": []},
        "elites": [
            {
                "rank": 1,
                "x": [0.5],
                "fitness": 3.0,
                "objective": {"cond": 2.0},
                "estimates": estimates,
                "failures": failures,
                "path_csv": None,
            }
        ],
        "chosen_elite": 1,
    }
