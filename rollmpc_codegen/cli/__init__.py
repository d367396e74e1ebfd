"""Command line: one module per subcommand (``rollmpc generate|simulate|bench|report|testvectors``)
and ``options`` for the option groups they share. These modules only parse, call the library
and print; ``main`` builds the parser and maps expected failures to one line and exit 2."""
