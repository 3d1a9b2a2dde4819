"""Code library: structured-light codes as exact `Code` values."""

from .code import Code, digits_to_int, gray, int_to_digits, inverse_gray
from .registry import get_code, names

__all__ = ["Code", "get_code", "names", "gray", "inverse_gray", "int_to_digits", "digits_to_int"]
