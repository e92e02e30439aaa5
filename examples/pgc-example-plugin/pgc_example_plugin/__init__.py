"""An example third-party PGC plugin: a separable, alpha-aware box-blur ``filter`` in numpy.

It is a separate distribution (``pip install -e examples/pgc-example-plugin``) that PGC finds through its
entry point ``example`` in the group ``pgc`` (see ``pyproject.toml`` and ``register.py``).
"""
