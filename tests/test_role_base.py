"""``RoleImplementation.input_checks``: every implementation's own definition of a checked method is wrapped
once, whatever the depth of subclassing; abstract methods and methods without a check are left alone."""

from __future__ import annotations

from abc import ABC, abstractmethod

import pytest

from pgc.errors import PGCDataError
from pgc.roles._base import RoleImplementation

CALLS: list[str] = []


def _positive(method):
    def checked(self, x):
        CALLS.append("check")
        if x <= 0:
            raise PGCDataError(f"{type(self).__name__}.{method.__name__}: x must be positive, got {x}")
        return method(self, x)

    return checked


class Toy(RoleImplementation, ABC):
    role = "toy"
    input_checks = {"run": _positive}

    @abstractmethod
    def run(self, x: float) -> float:
        """Twice ``x``."""

    def free(self, x: float) -> float:
        return x


class Impl(Toy):
    def run(self, x: float) -> float:
        """Twice ``x``, here."""
        return 2 * x


class Sub(Impl):
    def run(self, x: float) -> float:
        return super().run(x) + 1


class Inherits(Impl):
    pass


def test_each_definition_is_checked_once_and_keeps_its_name_and_docstring():
    CALLS.clear()
    assert Impl().run(3) == 6 and CALLS == ["check"]
    CALLS.clear()
    assert Sub().run(3) == 7 and CALLS == ["check", "check"]  # Sub.run, then Impl.run through super()
    CALLS.clear()
    assert Inherits().run(3) == 6 and CALLS == ["check"]  # inherited, not wrapped again
    assert Impl.run.__name__ == "run" and Impl.run.__doc__ == "Twice ``x``, here."
    assert Impl.run.inputs_checked and Inherits.run is Impl.run
    assert getattr(Toy.run, "__isabstractmethod__", False) and not hasattr(Toy.run, "inputs_checked")
    assert Impl().free(-1) == -1  # no check for it


def test_a_failing_check_names_the_implementation_and_stops_the_call():
    with pytest.raises(PGCDataError, match=r"Impl\.run: x must be positive, got -1"):
        Impl().run(-1)
