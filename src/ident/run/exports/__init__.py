"""Exports of the executable trajectory in the formats robot controllers run.

``controller.export: [ros2, urscript, franka]`` in a run config writes, besides
``trajectory.csv``, one export per name into ``<run>/exports/`` (:mod:`.registry`), each checked
against its controller's published rules before it is written and read back afterwards.
``docs/execute.md`` says how to run each file on the robot. Import the submodules directly.
"""
