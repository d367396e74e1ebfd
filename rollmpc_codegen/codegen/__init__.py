"""Stage 4 of the pipeline: the model becomes the render context (``context``, also written as
``P_context.json``, the contract between the maths and the C), the jinja2 templates render it
(``render``), and ``output`` writes the files, replacing only what rollmpc wrote."""
