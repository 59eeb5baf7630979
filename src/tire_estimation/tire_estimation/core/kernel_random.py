"""Random numbers inside compiled (Numba) kernels, seeded from an ``np.random.Generator``.

Why: a Numba kernel that calls ``rng.standard_normal()`` on a ``Generator`` pays a call through
the bit generator's function pointer for every word (about 9.4 ns per normal here, against
about 3 ns for the code below), and unboxing the ``Generator`` costs microseconds per kernel
call. The radius MPF draws about two normals per particle and wheel-speed sample, so this was
the largest single cost of a replay.

How: every kernel call takes a ``state`` array (4,) ``uint64`` filled by
:func:`kernel_state` from the caller's ``Generator`` (4 raw words of its bit generator, so a
seeded generator gives reproducible results and advances by 4 words per call). Inside the
kernel the words seed xoshiro256++ (Blackman & Vigna, "Scrambled linear pseudorandom number
generators", ACM TOMS 2021; reference C code at https://prng.di.unimi.it/, public domain),
which feeds

* :func:`uniform`: ``[0, 1)`` with 53 random bits,
* :func:`normal`: the ziggurat method of Marsaglia & Tsang (J. Stat. Softw. 5(8), 2000) with
  256 layers and 52-bit abscissae (the layout NumPy's ``standard_normal`` uses; tables built
  below with the paper's recursion), exact up to floating point,
* :func:`gamma`: Marsaglia & Tsang's squeeze method (ACM TOMS 26(3), 2000) for shape
  ``a >= 1``, and ``Gamma(a) = Gamma(a + 1) U^(1/a)`` below 1.

The streams differ from NumPy's ``Generator.standard_normal`` (not the same algorithm on the same
words); tests check the distributions and the generator against the reference C output.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

U64 = NDArray[np.uint64]

_M52 = float(2**52)


def _ziggurat_tables() -> tuple[NDArray[np.uint64], NDArray[np.float64], NDArray[np.float64]]:
    """``ki`` (256,) acceptance bounds, ``wi`` (256,) abscissa scales, ``fi`` (256,) densities.

    Marsaglia & Tsang (2000), section "The ziggurat method", with 256 strips of equal area
    ``v``: ``r = x_255`` the start of the tail, ``x_{i-1}`` from ``f(x_{i-1}) = v / x_i +
    f(x_i)``, ``f(x) = exp(-x^2 / 2)``; the base strip (index 0) has width ``q = v / f(r)``.
    """
    r = 3.6541528853610088
    v = 4.92867323399e-3
    f = math.exp(-0.5 * r * r)
    q = v / f
    ki = np.zeros(256, dtype=np.uint64)
    wi = np.zeros(256)
    fi = np.zeros(256)
    ki[0] = np.uint64(int((r / q) * _M52))
    ki[1] = np.uint64(0)
    wi[0] = q / _M52
    wi[255] = r / _M52
    fi[0] = 1.0
    fi[255] = f
    dn = tn = r
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(v / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = np.uint64(int((dn / tn) * _M52))
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / _M52
    return ki, wi, fi


ZIG_KI, ZIG_WI, ZIG_FI = _ziggurat_tables()
#: 1 / r of the ziggurat's tail
_ZIG_INV_R = 1.0 / 3.6541528853610088


def kernel_state(rng: np.random.Generator) -> U64:
    """Four raw words of ``rng``'s bit generator: the xoshiro256++ state of one kernel call."""
    s = np.asarray(rng.bit_generator.random_raw(4), dtype=np.uint64)
    if not s.any():  # the one forbidden state (probability 2^-256)
        s[0] = np.uint64(1)
    return s


#: xoshiro256++ state carried through a kernel as a tuple of four ``uint64`` (in registers;
#: an array state costs several nanoseconds per word)
State = tuple[np.uint64, np.uint64, np.uint64, np.uint64]
_U = np.uint64


@numba.njit(cache=True, inline="always")
def load(state: U64) -> State:
    """The tuple state of the array ``state`` (4,)."""
    return (state[0], state[1], state[2], state[3])


@numba.njit(cache=True, inline="always")
def store(state: U64, st: State) -> None:
    """Write the tuple state back into ``state`` (4,)."""
    state[0], state[1], state[2], state[3] = st


@numba.njit(cache=True, inline="always")
def next_u64(st: State) -> tuple[np.uint64, State]:
    """xoshiro256++ (Blackman & Vigna): the next 64-bit word and the advanced state."""
    s0, s1, s2, s3 = st
    x = s0 + s3
    # result = rotl(s0 + s3, 23) + s0
    result = ((x << _U(23)) | (x >> _U(41))) + s0
    t = s1 << _U(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    # s3 = rotl(s3, 45)
    s3 = (s3 << _U(45)) | (s3 >> _U(19))
    return result, (s0, s1, s2, s3)


@numba.njit(cache=True, inline="always")
def uniform(st: State) -> tuple[float, State]:
    """Uniform on ``[0, 1)``: the top 53 bits of a word times 2^-53."""
    r, st = next_u64(st)
    return float(r >> _U(11)) * (1.0 / 9007199254740992.0), st


@numba.njit(cache=True, error_model="numpy", inline="always")
def normal(st: State) -> tuple[float, State]:
    """Standard normal by the 256-strip ziggurat (Marsaglia & Tsang 2000)."""
    while True:
        r, st = next_u64(st)
        idx = np.intp(r & _U(0xFF))
        r >>= _U(8)
        sign = r & _U(1)
        rabs = (r >> _U(1)) & _U(0x000FFFFFFFFFFFFF)
        # x = +-U x_i (the sign without a branch: a random branch costs ~2 ns when mispredicted)
        x = float(rabs) * ZIG_WI[idx] * (1.0 - 2.0 * float(sign))
        # inside the strip's rectangle that lies under the density: accept (~99 %)
        if rabs < ZIG_KI[idx]:
            return x, st
        if idx == 0:
            # tail beyond r: Marsaglia (1964), x = -ln(U1) / r accepted if -2 ln(U2) > x^2
            while True:
                u1, st = uniform(st)
                u2, st = uniform(st)
                xx = -_ZIG_INV_R * math.log1p(-u1)
                yy = -math.log1p(-u2)
                if yy + yy > xx * xx:
                    t = 3.6541528853610088 + xx
                    return (-t if (rabs >> _U(8)) & _U(1) else t), st
        else:
            # wedge: a uniform height between f(x_i) and f(x_{i-1}) under the density
            u, st = uniform(st)
            if (ZIG_FI[idx - 1] - ZIG_FI[idx]) * u + ZIG_FI[idx] < math.exp(-0.5 * x * x):
                return x, st


@numba.njit(cache=True, error_model="numpy", inline="always")
def gamma(st: State, shape: float) -> tuple[float, State]:
    """``Gamma(shape, 1)``, ``shape > 0`` (Marsaglia & Tsang 2000, squeeze then exact test)."""
    boost = 1.0
    a = shape
    if shape < 1.0:
        # Gamma(a) = Gamma(a + 1) U^(1/a) (Marsaglia & Tsang, section 6)
        u, st = uniform(st)
        boost = u ** (1.0 / shape)
        a = shape + 1.0
    d = a - 1.0 / 3.0
    c = 1.0 / math.sqrt(9.0 * d)
    while True:
        x, st = normal(st)
        v = 1.0 + c * x
        if v <= 0.0:
            continue
        v = v * v * v
        u, st = uniform(st)
        x2 = x * x
        # squeeze: accept without a logarithm
        if u < 1.0 - 0.0331 * x2 * x2:
            return boost * d * v, st
        # exact test: ln U < x^2 / 2 + d (1 - V + ln V)
        if math.log(u) < 0.5 * x2 + d * (1.0 - v + math.log(v)):
            return boost * d * v, st


@numba.njit(cache=True)
def fill_u64(state: U64, out: U64) -> None:
    """Successive words into ``out`` (for tests against the reference implementation)."""
    st = load(state)
    for i in range(out.shape[0]):
        out[i], st = next_u64(st)
    store(state, st)


@numba.njit(cache=True)
def fill_normal(state: U64, out: NDArray[np.float64]) -> None:
    """Successive standard normals into ``out`` (tests, benchmarks)."""
    st = load(state)
    for i in range(out.shape[0]):
        out[i], st = normal(st)
    store(state, st)


@numba.njit(cache=True)
def fill_gamma(state: U64, shape: float, out: NDArray[np.float64]) -> None:
    """Successive ``Gamma(shape, 1)`` draws into ``out`` (tests, benchmarks)."""
    st = load(state)
    for i in range(out.shape[0]):
        out[i], st = gamma(st, shape)
    store(state, st)
