"""``python -m rollmpc_codegen.verify``: measure the figures of docs/reliability.md."""
import sys

from .reliability import main

sys.exit(main())
