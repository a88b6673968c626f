"""CPU time of the stages of :func:`plenodecode.calibrate_geometry` on generated F01 raws (issue 22 item 1).

``python -m bench gcal``: 8 captures of a 7 x 5 board of 4 mm squares (``simulate_checkerboard_set``, seed 0,
9 x 9 views of 113 x 128 samples, 45 views per capture searched) decoded as calibration decodes them
(``CAPTURE_DECODE``) with the grid fitted to the set's white image, then the stages timed one by one in process CPU seconds (the machine is shared: wall time
says little): decode, corner detection, the consistency check, the solve without and with distortion.

Measured (2 shared cores, load ~12, Nov 2026), CPU s, before -> after the changes of branch wt-gcal:
detection 32 (unchanged: a quick search before the exhaustive one saved 20 % but slid small boards),
solve with distortion 77 -> 4.0 and without 35 -> 1.5 (Levenberg-Marquardt on the normal equations instead of
least_squares' LSMR steps, which stopped at 200 evaluations per stage unconverged).
"""

from __future__ import annotations

import time

from . import Figure

BOARD = (7, 5, 0.004)
CAPTURES = 8


def _cpu(fn):
    start = time.process_time()
    result = fn()
    return result, time.process_time() - start


def run() -> list[Figure]:
    from plenodecode.calib import calibrate
    from plenodecode.calib.geometry.captures import CAPTURE_DECODE
    from plenodecode.calib.geometry.corners import consistent_views, detect_corners
    from plenodecode.calib.geometry.initial import initial_estimate
    from plenodecode.calib.geometry.solve import Observations, solve
    from plenodecode.decoding import decode
    from plenodecode.raymodel import Board
    from plenodecode.synthetic.checkerboard import simulate_checkerboard_set

    board = Board.of(BOARD)
    cset = simulate_checkerboard_set("f01", board, CAPTURES, seed=0)
    grid = calibrate(cset.white)
    decode(cset.raws[0], grid, white=cset.white, **CAPTURE_DECODE)       # compile the kernels
    lfs, t_decode = _cpu(lambda: [decode(raw, grid, white=cset.white, **CAPTURE_DECODE)
                                  for raw in cset.raws])
    found, t_detect = _cpu(lambda: [detect_corners(lf, board) for lf in lfs])
    _, t_check = _cpu(lambda: [consistent_views(f.views, f.corners) for f in found])
    obs = Observations.of(found, board)
    h, poses = initial_estimate(found, board)
    _, t_plain = _cpu(lambda: solve(obs, h, poses, distortion=False))
    _, t_full = _cpu(lambda: solve(obs, h, poses, distortion=True))
    views = sum(f.count for f in found)
    return [Figure(f"geometry stages, {CAPTURES} F01 captures: decode (CPU s)", t_decode),
            Figure(f"geometry stages: detect corners in {views} views (CPU s)", t_detect),
            Figure("geometry stages: consistency check (CPU s)", t_check),
            Figure("geometry stages: solve without distortion (CPU s)", t_plain),
            Figure("geometry stages: solve with distortion (CPU s)", t_full)]
