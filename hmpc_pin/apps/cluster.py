"""The package's Dask cluster: ``dask.distributed`` (optional extra ``cluster``) with a
one-line error naming the extra, and a local cluster of single-threaded worker processes
(``--executor dask`` of ``hmpc-pin sweep`` and ``hmpc-pin tune``)."""

from __future__ import annotations

from ..exceptions import ConfigError, install_command

__all__ = ["dask_client", "dask_modules", "local_cluster"]


def dask_modules():
    """``dask.distributed``.

    Raises:
        ConfigError: (key ``--executor``) it is not installed; the message names the
            extra ``cluster`` and its install command.
    """
    try:
        import dask.distributed
    except ImportError as exc:
        raise ConfigError(
            "--executor",
            "dask needs the optional dependency dask.distributed (extra hmpc_pin[cluster]); "
            f"install it with `{install_command('cluster')}` or use --executor local",
        ) from exc
    return dask.distributed


def local_cluster(jobs: int):
    """A local Dask cluster of ``jobs`` single-threaded worker processes.

    Raises:
        ConfigError: ``dask.distributed`` is not installed (:func:`dask_modules`).
    """
    return dask_modules().LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True)


def dask_client(jobs: int, scheduler: str | None):
    """A Dask client of the scheduler at the address ``scheduler``, or of a new
    :func:`local_cluster` of ``jobs`` processes when ``None``: ``(client, cluster)``, the
    cluster ``None`` when the scheduler was given (the caller closes the one it got).

    Raises:
        ConfigError: ``dask.distributed`` is not installed (:func:`dask_modules`).
    """
    Client = dask_modules().Client
    if scheduler:
        return Client(scheduler), None
    cluster = local_cluster(jobs)
    return Client(cluster), cluster
