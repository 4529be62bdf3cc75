"""`python -m docrl_jax.export`: a trained run's actor as deployment artefacts (docs/DEPLOY.md).

    python -m docrl_jax.export --policy td3_lstm --out export/td3_lstm     # a policy shipped in the package
    python -m docrl_jax.export --run runs/d --out export/d     # the run's policy: best where kept, else final
    python -m docrl_jax.export --run runs/d --seed-index 2 --which final --out export/d2_final
    python -m docrl_jax.export --run runs/d --out export/d --formats stablehlo,numpy --force

Bad input (an unknown --policy, a missing run, a seed index the run does not have, --which best on a run that kept no
best policy, an --out that cannot be written or already holds an export, the ONNX format without
its packages) is one line on stderr and exit status 2, before anything is converted.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from docrl_jax import flags, pretrained
from docrl_jax.arguments import OneLineParser, UsageError, check_out, prog
from docrl_jax.errors import ExportError, RunDirError, os_error_line
from docrl_jax.export.artefacts import DEFAULT_OPSET, FORMATS

def build_parser() -> argparse.ArgumentParser:
    from docrl_jax.evaluate.cli import add_which_argument
    p = OneLineParser(prog=prog("export"), description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    flags.add(src, "--run", "", metavar="RUN_DIR")
    flags.add(src, "--policy", f": a trained one shipped in the package, {', '.join(pretrained.PRETRAINED)}",
              metavar="NAME")
    p.add_argument("--seed-index", type=int, default=0, help="which seed of the run (default 0)")
    add_which_argument(p)
    flags.add(p, "--out", ": a folder (created)", metavar="DIR", required=True)
    p.add_argument("--force", action="store_true", help="replace an export already in --out")
    p.add_argument("--formats", default=",".join(FORMATS),
                   help=f"comma-separated, of {', '.join(FORMATS)} (default all three)")
    p.add_argument("--opset", type=int, default=DEFAULT_OPSET, help=f"ONNX opset (default {DEFAULT_OPSET})")
    p.add_argument("--platforms", default="cpu",
                   help="platforms the StableHLO artefact is lowered for, comma-separated (default cpu; "
                        "e.g. cpu,cuda for a GPU host too)")
    return p


def _shipped(name: str) -> str:
    """A --policy name the export takes: a shipped policy (bba is a controller, not a network)."""
    from docrl_jax.schema import did_you_mean
    name = name.lower()
    if name not in pretrained.PRETRAINED:
        raise pretrained.UnknownPolicy(f"--policy {name!r}: valid choices: {', '.join(pretrained.PRETRAINED)} (the "
                                       "trained policies shipped in the package; bba is a controller, not a network "
                                       f"to export), or --run RUN_DIR{did_you_mean(name, pretrained.PRETRAINED)}")
    return name


def _fail(message: str) -> int:
    print(f"{prog('export')}: error: {message}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from docrl_jax.export import check_formats, export_policy, export_shipped
    formats = [f.strip() for f in args.formats.split(",") if f.strip()]
    platforms = tuple(p.strip() for p in args.platforms.split(",") if p.strip())
    try:
        if args.seed_index < 0:
            raise ExportError(f"--seed-index {args.seed_index}: must be >= 0")
        if not platforms:
            raise ExportError("--platforms: give at least one, e.g. cpu")
        check_formats(formats)
        if args.policy is not None and (args.which is not None or args.seed_index != 0):
            raise ExportError("--which and --seed-index choose within a run: a shipped --policy is one seed's final "
                              "policy")
        name = _shipped(args.policy) if args.policy is not None else None
        check_out(args.out)
        if name is not None:
            result = export_shipped(name, args.out, formats=formats, force=args.force,
                                    opset=args.opset, platforms=platforms)
        else:
            result = export_policy(args.run, args.out, seed_index=args.seed_index, which=args.which,
                                   formats=formats, force=args.force, opset=args.opset, platforms=platforms)
    except (RunDirError, ExportError, ImportError, pretrained.UnknownPolicy, UsageError) as e:
        return _fail(str(e))
    except OSError as e:   # an --out that cannot be made or written
        return _fail(os_error_line(e))
    check = result["check"]["max_abs_action_diff"]
    print(f"{result['source']['policy']} ({result['policy']['config']}) -> {args.out}")
    for name, entry in result["files"].items():
        files = entry if isinstance(entry, str) else ", ".join(
            v for k, v in entry.items() if k in ("file", "weights", "loader"))
        diff = check.get(name)
        note = "" if diff is None else (f"  (max |action - JAX| {diff:.1e} over {result['check']['steps']} steps)"
                                        if isinstance(diff, float) else f"  ({diff})")
        print(f"  {name}: {files}{note}")
    return 0


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
