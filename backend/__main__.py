"""``python -m backend [--host H] [--port P] [--db FILE]``: the REST API alone (no web app).

``nmkane serve`` is the user's entry point; this one is for tests and scripts.
"""

import argparse
from pathlib import Path

from .config import Settings
from .serve import serve

parser = argparse.ArgumentParser(prog="python -m backend", description="nmkane REST API (no 3D web app)")
parser.add_argument("--host", default="127.0.0.1", help="address to bind (default: loopback)")
parser.add_argument("--port", type=int, default=8000, help="port (0: a free one)")
parser.add_argument("--db", type=Path, help="SQLite file (default: $NMKANE_DB or $NMKANE_DATA_DIR/runs.sqlite3)")
args = parser.parse_args()
settings = Settings() if args.db is None else Settings(db_path=args.db)
serve(host=args.host, api_port=args.port, web=False, settings=settings)
