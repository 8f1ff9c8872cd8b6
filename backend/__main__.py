"""``python -m backend [--host H] [--port P]``: the REST service alone (used by tests)."""

import argparse

from .serve import serve

parser = argparse.ArgumentParser(prog="python -m backend")
parser.add_argument("--host", default="127.0.0.1")
parser.add_argument("--port", type=int, default=8000)
args = parser.parse_args()
serve(host=args.host, api_port=args.port, web=False)
