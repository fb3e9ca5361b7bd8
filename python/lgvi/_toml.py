"""TOML text for the compiled scenario reader, written by the compiled writer (lgvi._core.toml_text:
src/io/toml_writer.hpp, the CLI's), so that scenarios and sweeps built in code are spelled as the CLI
spells its own (floats as repr spells them) and get exactly the file reader's validation and
messages. The layer above _columns, _check and _attitude; _api and _ensemble write their TOML with
it. The compiled module is imported on the first call, so that importing this module needs none."""


def toml_text(document):
    """A document -- a dict of tables, each a dict of bool, int, float, str, lists and dicts -- as TOML
    text: every table, its keys in sorted order; a list of dicts is an array of tables ([[key]]), a dict
    inside a table an inline table. TypeError for a value TOML cannot hold (a numpy array: .tolist()),
    ValueError for an int beyond 64 bits."""
    from . import _core
    return _core.toml_text(document)
