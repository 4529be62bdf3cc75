"""The robustness benchmark's outputs (docrl_jax.evaluate.robustness): robustness.csv (one row per
method, seed, test, perturbation, magnitude, scenario, direction and tank: the outcome counts and
the success rate), robustness.json (those rows, the rows over seeds and the run's settings: command,
versions, date), robustness.md (success % per test and magnitude, A-W / W-A; the tanks test per tank)
and robustness.png (success against magnitude per perturbation, a bar panel for the trip tests).

The tanks test's rows carry the tank: "all" for its rows over the set (those the summary tables and
the figure show), a tank's name for its rows per tank (the "Per tank" table); every other row "".

Where a method has several seeds the table and figure show, for each cell, the median over seeds of
the seed's success rate averaged over the scenarios (every scenario runs the same number of trials).
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path
from typing import Sequence

import numpy as np

from docrl_jax.evaluate.tables import SHORT

CSV_FIELDS = ("method", "seed_index", "test", "perturbation", "magnitude", "value", "parameter", "scenario",
              "direction", "tank", "trials", "successes", "collisions", "out_of_bounds", "timeouts", "diverged",
              "success_rate", "final_distance_mean", "path_length_all_mean", "time_mean", "seconds")
GROUP = ("method", "test", "perturbation", "magnitude", "scenario", "direction", "tank")
TEST_TITLES = {"random_trips": "Random trips", "held_out_layouts": "Held-out layouts (scenario 0)",
               "structured": "Held-out structured layouts (scenario 0)", "tanks": "Tanks"}
BAR_LABELS = {"random_trips": "random", "held_out_layouts": "layouts", "structured": "structured",
              "tanks": "tanks"}
SCENARIO_0 = ("held_out_layouts", "structured", "tanks")   # the tests in scenario 0 only
ALL_TANKS = "all"     # the tank of the tanks test's rows over the whole set
PACKAGES = ("docrl_jax", "jax", "jaxlib", "mujoco", "mujoco-mjx", "flax", "numpy", "matplotlib")
NOMINAL = "nominal"   # the perturbation of the sweep's row without one
NONE = "none"         # the perturbation of the random and layout trips' rows


def over_seeds(rows: Sequence[dict]) -> list[dict]:
    """One row per (method, test, perturbation, magnitude, scenario, direction): the success rate's
    median, min and max over seeds, each seed's successes, and the median outcome counts."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(k, "") for k in GROUP), []).append(r)
    out = []
    for key, rs in groups.items():
        rates = [r["success_rate"] for r in rs]
        agg = dict(zip(GROUP, key))
        agg.update(value=rs[0]["value"], parameter=rs[0]["parameter"], trials=rs[0]["trials"],
                   seeds=[r["seed_index"] for r in rs], successes_per_seed=[r["successes"] for r in rs],
                   success_rate_median=statistics.median(rates), success_rate_min=min(rates),
                   success_rate_max=max(rates))
        for k in ("collisions", "out_of_bounds", "timeouts"):
            agg[f"{k}_median"] = statistics.median(r[k] for r in rs)
        out.append(agg)
    return out


def cell_rates(rows: Sequence[dict], per_scenario: bool = False) -> dict[tuple, float]:
    """(method, test, perturbation, magnitude, direction[, scenario]) -> success rate: each seed's
    rate averaged over the scenarios (or one scenario's), then the median over seeds."""
    per_seed: dict[tuple, dict] = {}
    for r in rows:
        key = (r["method"], r["test"], r["perturbation"], r["magnitude"], r["direction"])
        if per_scenario:
            key += (r["scenario"],)
        per_seed.setdefault(key, {}).setdefault(r["seed_index"], []).append(r["success_rate"])
    return {k: statistics.median(float(np.mean(v)) for v in seeds.values()) for k, seeds in per_seed.items()}


def per_tank(row: dict) -> bool:
    """A row of one tank of the tanks test (not the set's)."""
    return row.get("tank", "") not in ("", ALL_TANKS)


def tank_table(rows: Sequence[dict], sample: Sequence[str] | None = None) -> list[str]:
    """Markdown lines: success % and trials per tank of the tanks test (A-W / W-A, median over seeds);
    `sample`: the tanks a --quick run flew of its set (meta's tank_sample)."""
    tank_rows = [r for r in rows if per_tank(r)]
    if not tank_rows:
        return []
    dirs = list(dict.fromkeys(r["direction"] for r in tank_rows))
    methods = list(dict.fromkeys(r["method"] for r in tank_rows))
    rates = {}
    for r in tank_rows:
        rates.setdefault((r["tank"], r["method"], r["direction"]), {})[r["seed_index"]] = r
    out = ["", "## Per tank\n", f"Tanks test: success % ({' / '.join(SHORT[d] for d in dirs)}) and trials in each tank "
           + (f"(--quick: {len(sample)} tanks spread evenly over the set; trial i flies in the i-th of them mod "
              f"{len(sample)}); " if sample else "(trial i flies in tank i mod the set's size); ")
           + "median over seeds.\n",
           "| Tank | Method | Success | Trials |", "|---|---|---|---|"]
    for tank in dict.fromkeys(r["tank"] for r in tank_rows):
        for m in methods:
            cells = [rates.get((tank, m, d), {}) for d in dirs]
            pct = " / ".join(_pct(statistics.median(r["success_rate"] for r in c.values()) if c else None)
                             for c in cells)
            n = " / ".join(str(next(iter(c.values()))["trials"]) if c else "–" for c in cells)
            out.append(f"| {tank} | {m} | {pct} | {n} |")
    return out


def _lines(rows: Sequence[dict]) -> list[tuple[str, str]]:
    """(test, perturbation) in the order the rows first name them."""
    return list(dict.fromkeys((r["test"], r["perturbation"]) for r in rows))


def _magnitudes(rows: Sequence[dict], test: str, perturbation: str) -> list[tuple[str, float | None]]:
    return list(dict.fromkeys((r["magnitude"], r["value"]) for r in rows
                              if r["test"] == test and r["perturbation"] == perturbation))


def _title(test: str, perturbation: str, envelope: dict) -> str:
    if test != "perturbations":
        return TEST_TITLES[test]
    if perturbation == NOMINAL:
        return "Nominal (the paper's pairs)"
    return f"{envelope[perturbation].title} (`{envelope[perturbation].param}`)"


def _pct(rate: float | None) -> str:
    return "–" if rate is None or not math.isfinite(rate) else f"{100 * rate:.0f}"


def markdown(rows: Sequence[dict], meta: dict, envelope: dict) -> str:
    """The summary table (success %, A-W / W-A, averaged over scenarios, median over seeds) and one
    per scenario, and the tanks test per tank; `envelope`: perturbation name -> its `robustness.Perturbation`."""
    rows, all_rows = [r for r in rows if not per_tank(r)], rows
    rates, by_scen = cell_rates(rows), cell_rates(rows, per_scenario=True)
    methods = list(dict.fromkeys(r["method"] for r in rows))
    seeds = {m: len({r["seed_index"] for r in rows if r["method"] == m}) for m in methods}
    dirs = list(dict.fromkeys(r["direction"] for r in rows))
    lines_ = _lines(rows)
    width = max([len(_magnitudes(rows, t, p)) for t, p in lines_] or [1])
    scen = sorted({r["scenario"] for r in rows if r["test"] not in SCENARIO_0})
    where = (f"averaged over scenarios {', '.join(map(str, scen))}" if len(scen) > 1
             else f"in scenario {scen[0]}" if scen else "")
    tests = {r["test"] for r in rows}
    layouts = "; ".join(
        ([f"held-out layouts: scenario 0, {meta['layouts']} layouts"] if "held_out_layouts" in tests else [])
        + ([f"structured: {meta['layouts']} layouts"] if "structured" in tests else [])
        + ([f"tanks: {meta.get('tank')}, {meta['trials']} trials"] if "tanks" in tests else []))
    out = ["# Robustness benchmark\n",
           f"Success % ({' / '.join(SHORT[d] for d in dirs)}) {where}{f' ({layouts})' if layouts else ''}; "
           f"{meta['trials']} trials per scenario, direction and magnitude; median over seeds where a method has "
           "several. Counts of collisions, out-of-bounds and time-outs: robustness.csv.\n",
           "| Test | Method | " + " | ".join(f"Magnitude {i + 1}" if width > 1 else "Success"
                                              for i in range(width)) + " |",
           "|---|---|" + "---|" * width]
    for test, pert in lines_:
        mags = _magnitudes(rows, test, pert)
        for m in methods:
            cells = []
            for mag, _ in mags:
                rs = " / ".join(_pct(rates.get((m, test, pert, mag, d))) for d in dirs)
                cells.append(f"{mag}: {rs}" if mag else rs)
            name = m + (f" ({seeds[m]} seeds)" if seeds[m] > 1 else "")
            cells += [""] * (width - len(cells))
            out.append(f"| {_title(test, pert, envelope)} | {name} | " + " | ".join(cells) + " |")
    cols = list(dict.fromkeys((r["scenario"], r["direction"]) for r in sorted(rows, key=lambda r: r["scenario"])))
    out += ["", "## Per scenario\n", "Success % per scenario (S0: procedural tanks, the layout and tank tests).\n",
            "| Test | Magnitude | Method | " + " | ".join(f"S{s} {SHORT[d]}" for s, d in cols) + " |",
            "|---|---|---|" + "---|" * len(cols)]
    for test, pert in lines_:
        for mag, _ in _magnitudes(rows, test, pert):
            for m in methods:
                cells = [_pct(by_scen.get((m, test, pert, mag, d, s))) if (m, test, pert, mag, d, s) in by_scen
                         else "" for s, d in cols]
                out.append(f"| {_title(test, pert, envelope)} | {mag or '–'} | {m} | " + " | ".join(cells) + " |")
    out += tank_table(all_rows, meta.get("tank_sample"))
    return "\n".join(out) + "\n"


def plot(rows: Sequence[dict], path: Path, envelope: dict, title: str = "") -> Path:
    """Success % against magnitude, one panel per perturbation (the nominal point among the
    magnitudes in order of value, evenly spaced), a line per method and direction (averaged over
    scenarios, median over seeds); a bar panel for the random trips and held-out layouts."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = [r for r in rows if not per_tank(r)]
    rates = cell_rates(rows)
    methods = list(dict.fromkeys(r["method"] for r in rows))
    dirs = list(dict.fromkeys(r["direction"] for r in rows))
    perts = [p for t, p in _lines(rows) if t == "perturbations" and p != NOMINAL]
    trips = [t for t in BAR_LABELS if any(r["test"] == t for r in rows)]
    has_nominal = any(r["test"] == "perturbations" and r["perturbation"] == NOMINAL for r in rows)
    panels = perts + (["trips"] if trips else []) or ([NOMINAL] if has_nominal else [])
    ncols = min(4, max(1, len(panels)))
    nrows = math.ceil(len(panels) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.2 * nrows), squeeze=False)
    colours = {m: plt.get_cmap("tab10")(i % 10) for i, m in enumerate(methods)}
    styles = {"air_to_water": ("-", "o"), "water_to_air": ("--", "s")}
    for ax, panel in zip(axes.ravel(), panels):
        if panel == "trips":
            labels = [f"{BAR_LABELS[t]}\n{SHORT[d]}" for t in trips for d in dirs]
            width = 0.8 / len(methods)
            for i, m in enumerate(methods):
                vals = [100 * rates.get((m, t, NONE, "", d), math.nan) for t in trips for d in dirs]
                ax.bar(np.arange(len(labels)) + (i - (len(methods) - 1) / 2) * width, vals, width,
                       color=colours[m], label=m)
            ax.set_xticks(np.arange(len(labels)), labels, fontsize=8)
            ax.set_title("Trips: " + ", ".join(BAR_LABELS[t] for t in trips), fontsize=10)
        else:
            p = envelope.get(panel)
            points = [("", p.nominal if p else 0.0)] if has_nominal else []
            points += [(mag, v) for mag, v in _magnitudes(rows, "perturbations", panel)] if p else []
            points.sort(key=lambda mv: mv[1])
            for m in methods:
                for d in dirs:
                    ys = [100 * rates.get((m, "perturbations", NOMINAL if not mag else panel, mag, d), math.nan)
                          for mag, _ in points]
                    ls, mk = styles[d]
                    ax.plot(range(len(points)), ys, ls, marker=mk, color=colours[m], label=f"{m} {SHORT[d]}")
            # Evenly spaced in order of magnitude: the magnitudes span 0 to 10x, a value axis crowds them.
            ticks = [(p.label(v) if p else "nominal") + ("\n(nominal)" if not mag and p else "") for mag, v in points]
            ax.set_xticks(range(len(points)), ticks, fontsize=8)
            ax.set_title(p.title if p else "Nominal", fontsize=10)
        ax.set_ylim(-3, 103)
        ax.set_ylabel("success %", fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(panels):]:
        ax.axis("off")
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    if panels and panels[0] == "trips":
        handles, labels = handles[:len(methods)], labels[:len(methods)]
    fig.legend(handles, labels, loc="lower center", ncol=min(6, max(1, len(labels))), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0.06 if nrows > 1 else 0.12, 1, 0.96 if title else 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def versions() -> dict[str, str | None]:
    from docrl_jax.resources import versions as installed
    return installed(PACKAGES)


def _clean(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, float):
        return round(x, 4)
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def write_outputs(out_dir: Path, rows: list[dict], meta: dict, envelope: dict) -> list[Path]:
    """robustness.csv, robustness.json, robustness.md and robustness.png in `out_dir`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"robustness.{ext}" for ext in ("csv", "json", "md", "png")]
    with open(paths[0], "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(_clean(r) for r in rows)
    paths[1].write_text(json.dumps(_clean({"meta": meta, "rows": rows, "over_seeds": over_seeds(rows)}), indent=1))
    paths[2].write_text(markdown(rows, meta, envelope))
    labels = ", ".join(dict.fromkeys(r["method"] for r in rows))
    plot(rows, paths[3], envelope, title=f"Robustness: {labels}")
    return paths
