"""The generated C on the host: compile and load it through cffi (``build``, with the private
verified cache of ``build_cache``), stand-alone test programs (``programs``, ``testvectors``),
and ``rollmpc bench`` against the PyPI peers (``bench*``)."""
