"""The paper's reported figures, printed next to ours for comparison.

Real-arm results (its Table 1, ten trials per cell) and its simulated empty-cup table. SR as a
fraction, OI as the mean count of exploratory interactions, time as (mean, std) in seconds.
The paper's timings are of a real arm or of a different simulated robot, so only SR and OI
are comparable in kind; the times are shown for reference.
"""

from __future__ import annotations

#: (task, variant) -> (SR, OI, (time mean s, time std s)).
PAPER_TABLE_1 = {
    ("find_blue_cube", "cap"): (10 / 10, 3.0, (75.51, 4.0)),
    ("find_blue_cube", "cap_physx"): (10 / 10, 2.7, (76.91, 21.0)),
    ("find_blue_cube", "cap_physx_planner"): (9 / 10, 3.0, (104.11, 26.0)),
    ("find_blue_cube", "physcap_joint"): (8 / 10, 2.125, (65.91, 23.0)),
    ("find_blue_cube", "physcap"): (9 / 10, 1.33, (40.48, 15.0)),
    ("identify_empty_can", "cap"): (2 / 10, 2.5, (71.71, 20.0)),
    ("identify_empty_can", "cap_physx"): (7 / 10, 3.9, (268.08, 16.0)),
    ("identify_empty_can", "cap_physx_planner"): (7 / 10, 4.0, (274.14, 77.0)),
    ("identify_empty_can", "physcap_joint"): (7 / 10, 2.7, (241.62, 70.0)),
    ("identify_empty_can", "physcap"): (8 / 10, 2.5, (239.0, 27.0)),
    ("pick_ripe_avocado", "cap"): (1 / 10, 1.0, (26.38, 0.0)),
    ("pick_ripe_avocado", "cap_physx"): (9 / 10, 4.0, (515.61, 9.0)),
    ("pick_ripe_avocado", "cap_physx_planner"): (8 / 10, 4.125, (563.29, 76.0)),
    ("pick_ripe_avocado", "physcap_joint"): (7 / 10, 2.71, (384.39, 111.0)),
    ("pick_ripe_avocado", "physcap"): (9 / 10, 2.0, (300.47, 53.0)),
    # The simulated replica (LIBERO, a Franka arm); CaP and PhysCaP-joint were not run there.
    ("empty_cup", "cap_physx"): (0.74, 2.16, (70.81, 32.50)),
    ("empty_cup", "cap_physx_planner"): (0.62, 1.45, (79.55, 44.49)),
    ("empty_cup", "physcap"): (0.78, 1.44, (71.24, 18.63)),
}
