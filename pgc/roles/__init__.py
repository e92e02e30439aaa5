"""Role interfaces. One module per role: the abstract class, its options base and its contract.

Implementations subclass the role class, declare ``Options`` (a :class:`pgc.options.Options` subclass,
in a light module so that ``pgc config show`` need not import the backend) and are constructed with a
validated options object.
"""
