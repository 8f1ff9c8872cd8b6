"""Pages generated at build time (run by mkdocs-gen-files; see mkdocs.yml).

Each generator writes the pages that follow the code, so they cannot go stale:

* ``reference/``: one page per name of ``nmkane_core.__all__`` (gen_reference);
* ``catalogue/``: the facts of every registered system, from ``GET /api/systems`` (gen_catalogue);
* ``cli.md``: every ``nmkane`` command, from its argparse parser (gen_cli);
* ``rest.md``: every route and schema, from ``backend.app.create_app().openapi()`` (gen_rest);
* ``how-it-works.md``: the sliding particle's matrices, derived now (gen_matrices).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1]))  # the checkout's nmkane_core, backend (not an installed copy)
os.environ["COLUMNS"] = "88"  # argparse wraps usage lines at this width: the width of a code block

import gen_catalogue  # noqa: E402
import gen_cli  # noqa: E402
import gen_matrices  # noqa: E402
import gen_reference  # noqa: E402
import gen_rest  # noqa: E402
import mkdocs_gen_files  # noqa: E402

for generator in (gen_reference, gen_catalogue, gen_cli, gen_rest, gen_matrices):
    for path, text in generator.pages().items():
        with mkdocs_gen_files.open(path, "w") as f:
            f.write(text)
