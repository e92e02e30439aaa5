"""Implementations of the ``body_model`` role (:mod:`pgc.roles.body_model`): ``anny`` and ``smplx``."""
