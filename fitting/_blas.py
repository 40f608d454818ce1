"""One BLAS thread while a fit runs (`single_threaded_blas`).

On the CPU, JAX's linear algebra (the QR of each Levenberg-Marquardt step, the final
covariance) calls the LAPACK of SciPy's OpenBLAS, and NumPy's own OpenBLAS does the host-side
products of a fit's stopping rules. On matrices of n x p with p ~ 10, OpenBLAS's threads
gain little, but after every call its worker threads keep spinning (busy-waiting for more
work) for a while, on the cores XLA's own threads and the compiled kernels need: on the
2-core benchmark machine a profile of ``fitting.fit(max_steps=1)`` at 1e5 samples spent
about half of its samples in those spinning threads
(``benchmarks/profiling/profile_fit_fixed.py`` measures a fit with and without this).

`single_threaded_blas` limits every BLAS loaded in the process to one thread for the
duration of a block, with ``threadpoolctl`` (about 1.4 ms per block), and restores the
previous counts afterwards. Results do not change: a one-thread BLAS does the same
arithmetic in the same blocks.

Fits side by side in threads need one block around them all, not only each fit's own:
``benchmarks/profiling/parallel_fits.py`` times two fits in two threads against one after
the other, and with per-fit blocks alone each fit of the pair costs 1.8-2.9x the CPU time
(the pair takes longer than the two in turn); with one block held around the pair, as long
as one fit alone. `fitting.diagnose`, whose fits run side by side
(`fitting._refits.Fitter.map`), holds one for all of its work.
"""

from threadpoolctl import threadpool_limits

from ._outermost import outermost


#: False: `single_threaded_blas` does nothing (for benchmarks/profiling/profile_fit_fixed.py,
#: which times fits both ways).
ENABLED = True

single_threaded_blas = outermost(
    lambda: threadpool_limits(limits=1, user_api="blas"),
    lambda limits: limits.restore_original_limits(),
    lambda: ENABLED,
    """Every BLAS of the process on one thread inside the block (module docstring); nested
    and concurrent blocks keep it so until the outermost one ends.""")
