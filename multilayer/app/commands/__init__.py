"""CLI subcommands: each module defines ``HELP``, ``add_arguments(parser)`` and ``main(args)``."""

import argparse


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (a bad value is a usage error, exit code 2)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def add_cluster_arguments(parser: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS`` or ``--workers N``: where Dask runs the members."""
    cluster = parser.add_mutually_exclusive_group()
    cluster.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: start a local cluster)",
    )
    cluster.add_argument(
        "--workers",
        metavar="N",
        type=positive_int,
        help="worker processes of the local cluster (default: one per core)",
    )


def cluster_description(args: argparse.Namespace) -> str:
    """Where the members run, in words, from the options of :func:`add_cluster_arguments`."""
    if args.scheduler is not None:
        return f"the Dask cluster at {args.scheduler}"
    if args.workers is not None:
        return f"a local Dask cluster of {args.workers} single-threaded worker process(es)"
    return "a local Dask cluster (one single-threaded worker process per core)"
