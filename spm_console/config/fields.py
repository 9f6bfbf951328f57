"""The value types of every profile key: numbers that are numbers, and the section base.

A :data:`Real` is a float or an int, never a bool or a string, finite and never subnormal;
a :data:`Count` is an int only; an :data:`Angle` lies within one turn either way. The
sections (:mod:`spm_console.config.schema`, :mod:`spm_console.config.plant`) build on these,
so one declaration holds for every key.
"""

from __future__ import annotations

import sys
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, Strict
from pydantic_core import PydanticCustomError

#: Largest |angle| of any angle in a profile (θ, grid range, limits, η), deg: one turn
#: either way covers every configuration; larger values only make grids and limits absurd.
ANGLE_LIMIT_DEG = 360.0


def _normal(value: float) -> float:
    """Refuse a subnormal magnitude (0 < |x| < 2.2e-308, below the smallest normal float):
    no quantity is that small, and arithmetic on it loses every digit or overflows (1/x)."""
    if value != 0 and abs(value) < sys.float_info.min:
        raise PydanticCustomError("subnormal_number", "a subnormal number, too small to be a "
                                  "quantity (write 0, or a value of physical size)")
    return value


#: A real number: float or int, never bool or str; finite (``allow_inf_nan=False`` below),
#: never subnormal.
Real = Annotated[float, Strict(), AfterValidator(_normal)]
#: An integer: never bool, float or str.
Count = Annotated[int, Strict()]
#: An angle within one turn either way, deg.
Angle = Annotated[float, Strict(), AfterValidator(_normal),
                  Field(ge=-ANGLE_LIMIT_DEG, le=ANGLE_LIMIT_DEG)]
#: A boolean: true or false, never a number or a string.
Flag = Annotated[bool, Strict()]
#: One entry of the sign seed.
Sign = Annotated[int, Strict(), Field(ge=-1, le=1)]
Vec3 = tuple[Angle, Angle, Angle]


def _whole(value: object) -> object:
    """Refuse a bool, float or str before a ``Literal`` of ints (which would accept them)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise PydanticCustomError("int_type", "Input should be a valid integer")
    return value


#: +1 or −1, strictly an int.
Direction = Annotated[Literal[1, -1], BeforeValidator(_whole)]


class Section(BaseModel):
    """A profile section: unknown keys refused, frozen, numbers finite, docstrings kept."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False,
                              use_attribute_docstrings=True)
