"""The identification pipeline: the top room of ``ident.identify``.

``core`` (:func:`~ident.identify.pipeline.core.identify_measurements`, the one identification
every command runs on joint-side measurements, and its
:class:`~ident.identify.pipeline.core.IdentifyResult`), ``estimates`` (its estimators,
essential parameters, held-out vectors, reference comparisons and warnings), ``records``
(the records of its processing) and ``real``
(:func:`~ident.identify.pipeline.real.identify`: ``ident identify`` on the log a config
names, with its time and memory estimate). Import the submodules directly.
"""
