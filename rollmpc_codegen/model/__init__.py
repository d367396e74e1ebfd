"""Stage 2 of the pipeline: each mode's plant as a discrete, well-scaled realisation
(``plant``, ``tf_realisation``), its observer gain (``observer``), and the frozen model of the
whole controller (``controller``); ``blas_kernels`` pins OpenBLAS's kernels so that this
maths gives the same bits on every x86-64 machine."""
