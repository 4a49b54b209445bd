"""Glue for Snakemake ``script:`` files: logging to the rule's log file, clean failure."""

from __future__ import annotations

import logging
import sys
import traceback
from collections.abc import Callable
from typing import Any


def run_rule(smk: Any, func: Callable[..., None], **kwargs: Any) -> None:
    """Run ``func(**kwargs)`` with stderr and logging sent to the rule's first log file.

    On failure the traceback goes to the log and the exception propagates, so Snakemake
    marks the job failed and removes its outputs (writers are atomic besides).
    """
    log_path = smk.log[0] if len(smk.log) else None
    stream = open(log_path, "w") if log_path else sys.stderr  # noqa: SIM115
    sys.stderr = stream
    logging.basicConfig(stream=stream, level=logging.INFO, force=True,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    try:
        func(**kwargs)
    except Exception:
        traceback.print_exc(file=stream)
        stream.flush()
        raise
    finally:
        stream.flush()
