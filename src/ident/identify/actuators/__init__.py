"""Actuators in identification: what turns a log into joint torques before the estimation.

``registry`` (one entry per ``actuator.kind``: ``motor``, the torque is logged; ``position``,
a servo logging its command and no torque) and ``servo_fit`` (the position servo's gain, delay
and saturation, the common scale fixed by the URDF's gravity load or a given gain). The laws
themselves are :mod:`ident.dynamics.actuators`, lower in the layers. Import the submodules
directly.
"""
