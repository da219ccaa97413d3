"""What a compiled call that takes a NumPy Generator costs, and whether Numba's Generator draws
the same numbers as NumPy's from the same state (it shares the state with the Python object).
Usage: generator_call.py"""
import timeit

import numpy as np


def main():
    import rearrangement_planner  # noqa: F401  (before numba)
    from numba import njit

    @njit
    def draws(rng, n):
        return rng.uniform(-1.0, 2.0, n), rng.random(4), rng.random(), rng.integers(0, 7)

    @njit
    def one(rng):
        return rng.random()

    @njit
    def plain(x):
        return x + 1.0

    a, b = np.random.default_rng(5), np.random.default_rng(5)
    same = all(np.array_equal(np.asarray(x), np.asarray(y)) for _ in range(100)
               for x, y in zip(draws(a, 7), (b.uniform(-1.0, 2.0, 7), b.random(4), b.random(),
                                             b.integers(0, 7))))
    print("same numbers as NumPy, state shared:", same and a.random() == b.random())
    one(a), plain(1.0)
    n = 50000
    for name, call in (("compiled call taking the Generator", lambda: one(a)),
                       ("compiled call taking a float", lambda: plain(1.0)),
                       ("NumPy rng.random()", lambda: a.random())):
        print(f"{name}: {timeit.timeit(call, number=n) / n * 1e6:.2f} us")


if __name__ == "__main__":
    main()
