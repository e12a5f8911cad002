"""Argument checks shared by the public constructors.

Every public entry point converts and checks its arguments here, so nothing reaches the native
core unchecked and every error names the argument it is about.
"""

import numbers

import numpy as np


def float_array(value, name, shape=None, dtype=np.float64, allow_nonfinite=False):
    """`value` as a C-contiguous float array; `shape` may use None for any length."""
    if value is None:
        raise TypeError(f"{name}: expected an array, got None")
    try:
        src = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected a numeric array ({exc})") from None
    if src.dtype.kind in "bcmMUSV":  # bool, complex, datetime, timedelta, text, records
        raise TypeError(f"{name}: expected real numbers, got dtype {src.dtype}")
    try:
        with np.errstate(over="ignore"):  # an overflowing cast is reported below, by name
            arr = np.array(value, dtype=dtype, copy=True, order="C")
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected a numeric array ({exc})") from None
    if arr.dtype == object:
        raise TypeError(f"{name}: expected a numeric array")
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if not allow_nonfinite and arr.size and not np.all(np.isfinite(arr)):
        # Finite input that overflowed the target dtype (e.g. 1e39 into float32, an OBJ uv of
        # 2e116: found by native/fuzz/fuzz_obj.py) is not "NaN or Inf": say what it is.
        with np.errstate(all="ignore"):
            src = np.asarray(value, dtype=np.float64)
        if src.shape == arr.shape and np.all(np.isfinite(src)):
            raise ValueError(f"{name}: values out of the {arr.dtype} range "
                             f"(largest magnitude {np.abs(src).max():.3g})")
        raise ValueError(f"{name}: contains NaN or Inf")
    return arr


def int_array(value, name, shape=None):
    """`value` as int32; float input is accepted when every entry is integral."""
    if value is None:
        raise TypeError(f"{name}: expected an integer array, got None")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected an integer array ({exc})") from None
    if raw.dtype == bool or raw.dtype == object or not np.issubdtype(raw.dtype, np.number):
        raise TypeError(f"{name}: expected an integer array, got dtype {raw.dtype}")
    if np.issubdtype(raw.dtype, np.floating):
        if raw.size and (not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw))):
            raise ValueError(f"{name}: expected integers, got non-integral values")
    if raw.size and (raw.max() > np.iinfo(np.int32).max or raw.min() < np.iinfo(np.int32).min):
        raise ValueError(f"{name}: values out of the 32-bit range")
    arr = np.ascontiguousarray(raw, dtype=np.int32)
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    return arr


def int_triple(value, name, low, high):
    """Three ints in [low, high] (a single int is repeated)."""
    if isinstance(value, numbers.Integral):
        value = (value,) * 3
    try:
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{name}: expected an int or three ints") from None
    if len(items) != 3:
        raise ValueError(f"{name}: expected three values, got {len(items)}")
    out = []
    for v in items:
        if isinstance(v, (bool, np.bool_)):
            raise TypeError(f"{name}: expected integers, got {v!r}")
        if not isinstance(v, numbers.Integral):
            if isinstance(v, numbers.Real) and float(v).is_integer():
                v = int(v)
            else:
                raise TypeError(f"{name}: expected integers, got {v!r}")
        if not low <= int(v) <= high:
            raise ValueError(f"{name}: each value must be between {low} and {high}, got {v}")
        out.append(int(v))
    return tuple(out)


def positive_int(value, name, low=1, high=None):
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected an integer, got {value!r}")
    if not isinstance(value, numbers.Integral):
        if isinstance(value, numbers.Real) and float(value).is_integer():
            value = int(value)
        else:
            raise TypeError(f"{name}: expected an integer, got {value!r}")
    value = int(value)
    if value < low or (high is not None and value > high):
        rng = f"between {low} and {high}" if high is not None else f"at least {low}"
        raise ValueError(f"{name}: must be {rng}, got {value}")
    return value


def finite_float(value, name):
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name}: must be finite, got {value}")
    return value


def flag(value, name):
    """True or False, nothing that merely converts to one ('no' is truthy)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected True or False, got {value!r}")
    return bool(value)
