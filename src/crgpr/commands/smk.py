"""Glue for Snakemake rules and ``script:`` files: config params, logging, clean failure."""

from __future__ import annotations

import copy
import logging
import sys
import traceback
from collections.abc import Callable, Mapping
from typing import Any


def config_subset(config: Mapping[str, Any], *keys: str) -> dict[str, Any]:
    """The config values at dotted ``keys`` (``"rod"``, ``"prefilter.n_t_out"``), nested as in
    ``config`` and with sorted keys: what a rule passes as ``params: cfg=...``.

    Snakemake stores every job's params and reruns the job when they change, so a rule that
    passes exactly the values its output depends on is rerun by a change of one of them and
    by nothing else. The rule function receives this dict as its ``cfg``: a value it reads
    but the rule did not declare is a ``KeyError``, never a silently stale result.
    """
    out: dict[str, Any] = {}
    for key in keys:
        parts = key.split(".")
        node: Any = config
        for i, part in enumerate(parts):
            if not isinstance(node, Mapping) or part not in node:
                raise KeyError(f"config has no key {'.'.join(parts[: i + 1])!r} (rule params {key!r})")
            node = node[part]
        dst = out
        for part in parts[:-1]:
            dst = dst.setdefault(part, {})
        dst[parts[-1]] = copy.deepcopy(node)
    return _sorted(out)


def _sorted(value: Any) -> Any:
    """Mappings with sorted keys, recursively (params compare by their repr)."""
    if isinstance(value, Mapping):
        return {k: _sorted(value[k]) for k in sorted(value)}
    if isinstance(value, list | tuple):
        return [_sorted(v) for v in value]
    return value


def limit_threads() -> None:
    """One BLAS/OpenMP thread in every numerical library loaded so far.

    OpenBLAS splits its work by thread count, so the last bits of a GP fit depend on it
    (measured: the GP prefilter's derivatives move by ~1e-8 between 1 and 2 threads, and
    the paper-feature CR-GPR rollout amplifies such differences). Snakemake already sets
    ``OPENBLAS_NUM_THREADS`` etc. to a rule's ``threads`` (1 here); this makes the same hold
    for the command line and for any executor.
    """
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


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
    limit_threads()
    try:
        func(**kwargs)
    except Exception:
        traceback.print_exc(file=stream)
        stream.flush()
        raise
    finally:
        stream.flush()
