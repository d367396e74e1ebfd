"""Stage 3 of the pipeline: the condensed QP of each mode (``condense``), the arrays the C stores,
declared once (``arrays``) and cast once to the storage precision (``storage``); beside them, for
measurement only, the extended-precision solution (``exact``) and the PyPI peers (``peers``)."""
