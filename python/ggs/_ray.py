"""Running independent tasks on a Ray cluster: the ``executor="ray"`` of :func:`ggs.bench.run`
and :func:`ggs.register_many`. Ray is optional (``pip install "ggs[ray]"``).

Each task reserves ``cpus`` of Ray's CPUs and runs ggs with exactly that many threads, so
the tasks that Ray packs onto one node never oversubscribe its cores. A task whose worker
dies (killed, out of memory, node lost) is run again by Ray up to ``retries`` times; what
still fails is handed to ``on_error`` with Ray's exception, so no task is lost silently.
"""

from __future__ import annotations

from typing import Any, Callable, Dict, Iterable, Tuple


def require_ray() -> Any:
    """The ``ray`` module, connected: to the cluster of ``RAY_ADDRESS`` or of an earlier
    ``ray.init(...)``, else to a new local one."""
    try:
        import ray
    except ImportError as e:
        raise ImportError(
            'executor="ray" needs Ray: pip install "ray>=2.9" (or pip install "ggs[ray]")'
        ) from e
    if not ray.is_initialized():
        ray.init()
    return ray


def run_tasks(
    fn: Callable[..., Any],
    calls: Iterable[Tuple[int, Tuple[Any, ...]]],
    *,
    cpus: int,
    retries: int,
    on_result: Callable[[int, Any], None],
    on_error: Callable[[int, BaseException], None],
) -> None:
    """Run ``fn(*args)`` for every ``(key, args)`` of ``calls`` as Ray tasks and call
    ``on_result(key, value)`` or ``on_error(key, exception)`` as each finishes, in the order
    they finish. On an exception in a callback or Ctrl-C the tasks not finished are
    cancelled and the exception is raised."""
    ray = require_ray()
    remote = ray.remote(num_cpus=cpus, max_retries=retries)(fn)
    pending: Dict[Any, int] = {remote.remote(*args): key for key, args in calls}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                key = pending.pop(ref)
                try:
                    value = ray.get(ref)
                except ray.exceptions.RayError as e:
                    on_error(key, e)
                else:
                    on_result(key, value)
    except BaseException:
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished or its worker gone: nothing to cancel
                pass
        raise
