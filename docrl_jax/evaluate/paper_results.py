"""The DoCRL paper's published Table I ("Mean and standard deviation metrics over 100 navigation
trials for all approaches"), transcribed from the paper.

Times are seconds (mean, std) over the successful trials; success is out of 100 trials.

Which scenario: the paper does not say. Its Methods section says the experiments use "the second
and more complex environment" (scenario 2, the four risers), and Figure 3's panels are labelled
`*_2_air_to_water` etc., so the table is taken to be scenario 2 (`TABLE_I_SCENARIO`). The paper's
text also gives starts/targets for scenarios 1 and 3 but no table for them.
"""

from __future__ import annotations

TABLE_I_SCENARIO = 2

NOTE = ("Paper rows: Table I of Grando et al. (DoCRL), 100 trials each, Gazebo/RotorS/UUV Simulator. The paper "
        "does not name the table's scenario; it is shown with scenario 2 (the paper trains and evaluates in "
        "'the second and more complex environment', and Figure 3's labels read '_2_').")

_ROWS = [
    # direction, method, t_air (mean, std), t_water (mean, std), successes out of 100
    ("air_to_water", "DoCRL-D", (14.55, 0.87), (11.19, 2.86), 100),
    ("air_to_water", "DoCRL-S", (72.02, 24.33), (9.97, 6.05), 70),
    ("air_to_water", "Sto.", (18.10, 7.91), (1.08, 2.38), 1),
    ("air_to_water", "Det.", (34.09, 23.85), (13.06, 12.98), 14),
    ("air_to_water", "BBA", (34.70, 30.22), (4.87, 6.16), 11),
    ("water_to_air", "DoCRL-D", (16.67, 10.44), (4.65, 0.69), 42),
    ("water_to_air", "DoCRL-S", (8.77, 7.23), (5.98, 1.90), 71),
    ("water_to_air", "Sto.", (15.33, 23.75), (14.9, 18.88), 12),
    ("water_to_air", "Det.", (27.58, 14.77), (12.65, 7.89), 13),
    ("water_to_air", "BBA", (38.01, 29.83), (3.79, 0.27), 32),
]

TABLE_I = [{"direction": d, "method": m, "t_air": a, "t_water": w, "success": s, "trials": 100}
           for d, m, a, w, s in _ROWS]

METHODS = ("DoCRL-D", "DoCRL-S", "Sto.", "Det.", "BBA")


def lookup(method: str, direction: str) -> dict:
    """The published row of `method` ("DoCRL-D", "DoCRL-S", "Sto.", "Det.", "BBA") and `direction`."""
    for row in TABLE_I:
        if row["method"] == method and row["direction"] == direction:
            return row
    raise KeyError(f"no paper row for {method!r} {direction!r}; methods: {', '.join(METHODS)}; "
                   "directions: air_to_water, water_to_air")
