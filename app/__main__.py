"""``python -m app``: the command line. Ctrl-C while the modules load (numpy, OpenGL: the first
half second) is the same quiet exit 130 as later, not a traceback."""
import sys

try:
    from app.cli import main
    code = main()
except KeyboardInterrupt:
    print("scanlight: interrupted", file=sys.stderr)
    code = 130
raise SystemExit(code)
