#!/usr/bin/python3
"""The C++ libraries are layered at link level (issue 27, the layout of src/): lgvi_io (src/io) uses no
symbol that lgvi_app (src/app) defines. tests/python/test_source_layers.py checks the #include lines; this
checks what the compiled objects call, which an include check cannot see (a declaration written by hand).

usage: check_library_layers.py LIBLGVI_IO.a LIBLGVI_APP.a    (run by ctest as layers.io_below_app)
"""
import subprocess
import sys


def symbols(archive, *flags):
    out = subprocess.run(["nm", "--format=posix", *flags, archive], capture_output=True, text=True, check=True)
    # posix format: "name type [value size]"; archive member headers end with ":" and are skipped.
    return {line.split()[0] for line in out.stdout.splitlines() if line and not line.endswith(":")}


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[-1])
    io, app = sys.argv[1:]
    needed = symbols(io, "--undefined-only")
    # Defined by app (text, data, read-only data, weak: every kind but undefined), and not by io itself:
    # an inline function or a template instantiated in both is the headers', not the application's.
    defined_app = symbols(app, "--defined-only") - symbols(io, "--defined-only")
    upward = sorted(needed & defined_app)
    if upward:
        demangled = subprocess.run(["c++filt"], input="\n".join(upward), capture_output=True, text=True).stdout
        sys.exit(f"lgvi_io uses {len(upward)} symbol(s) that lgvi_app defines (src/io must not call src/app):\n"
                 + demangled)
    print(f"lgvi_io: {len(needed)} undefined symbols, none of them lgvi_app's")


if __name__ == "__main__":
    main()
