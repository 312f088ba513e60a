"""The identified model's files: URDF, MJCF and joint extras.

``files`` (:func:`~ident.identify.model_files.files.model_files`, ``save_identified_model``:
the three texts, then written), ``urdf_update`` (the identified URDF: ``identified_urdf``,
``model_of_urdf``, ``parse_urdf``), ``urdf_edit`` (text edits of a URDF that keep its
layout), ``fused_bodies`` (links fused through fixed or locked joints) and ``mjcf`` (the MJCF
and the joint extras mapped to MuJoCo). Outside the rooms' layers contract: the estimators
read URDFs through ``urdf_update`` while ``files`` writes the estimators' summary. Import the
submodules directly.
"""
