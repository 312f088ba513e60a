"""Replay of trajectories in meshcat: static HTML pages and a live server on 127.0.0.1."""

from ident.viz.replay import ReplayScene, build_replay_scene, replay_html

__all__ = ["ReplayScene", "build_replay_scene", "replay_html"]
