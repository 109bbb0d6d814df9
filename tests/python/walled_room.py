"""A free room with walls on its border, the map the localization and face tests share."""

import numpy as np

from probslam import _core


def room(res=0.1, w=60, h=40):
    """An OccupancyGrid2D of w x h cells of res m: free inside, walls on the border."""
    g = _core.OccupancyGrid2D(res, w, h, origin=(0.0, 0.0))
    lo = np.full((h, w), -3.0)
    lo[0, :] = lo[-1, :] = lo[:, 0] = lo[:, -1] = 3.0
    g.log_odds[:] = lo
    return g
