"""The library's patches by entry pose class, as flat tables for the interactive tiling's
vectorized candidate search (Kim, Hwang, Hyun and Lee 2012, section 5.3)."""
from __future__ import annotations

import numpy as np

from .prepared import PreparedLibrary, align_on_port

__all__ = ["EntryTables"]


class EntryTables:
    """Per entry pose class ``cls``, ``tables[cls]`` is a dict of arrays over the library's
    open entries of that class: ``p`` patch, ``j`` port, ``multi`` (a multi-character patch),
    ``pxz`` / ``pdir`` / ``ptime`` the entry and ``exz`` / ``edir`` its fragment's exit (patch
    frame), ``label`` the log label factor of Eq. 7 (f4), ``stand`` (a single-character idle
    patch). ``mobile[cls]``: a walking pose class (several single patches leave it by half a
    metre or more).

    Args:
        prepared: the :class:`~runtime.tiling.prepared.PreparedLibrary`.
        label_cost: Eq. 7 label costs (``f4``), by label.
    """

    def __init__(self, prepared: PreparedLibrary, label_cost: dict):
        self.log_label = np.array([-sum(label_cost.get(l, 0.0) for l in pp.patch.labels) for pp in prepared.patches])
        self.tables: dict = {}
        for (kind, cls), arr in prepared.by_port.items():
            if kind != 0:
                continue
            p, j = arr[:, 0], arr[:, 1]
            pps = [prepared.patches[int(q)] for q in p]
            self.tables[cls] = {
                "p": p, "j": j, "multi": np.array([pp.K > 1 for pp in pps]),
                "pxz": np.array([pp.port_xz[jj] for pp, jj in zip(pps, j)]),
                "pdir": np.array([pp.port_dir[jj] for pp, jj in zip(pps, j)]),
                "ptime": np.array([pp.port_time[jj] for pp, jj in zip(pps, j)]),
                "exz": np.array([pp.port_xz[jj + 1] for pp, jj in zip(pps, j)]),
                "edir": np.array([pp.port_dir[jj + 1] for pp, jj in zip(pps, j)]),
                "label": self.log_label[p],
                "stand": np.array([("idle" in pp.patch.labels) and pp.K == 1 for pp in pps]),
            }
        self.mobile = {cls: int(np.count_nonzero(~c["multi"] & (np.hypot(*(c["exz"] - c["pxz"]).T) >= 0.5))) >= 3
                       for cls, c in self.tables.items()}

    def get(self, cls: int):
        """The table of entry class ``cls``, or None if no patch enters it."""
        return self.tables.get(cls)

    @staticmethod
    def align(c: dict, k: int, row) -> tuple:
        """The rigid placement putting entry ``k`` of table ``c`` on the exit ``row``."""
        return align_on_port(c["pxz"][k], c["pdir"][k], c["ptime"][k], row)

    @staticmethod
    def aligned_origins(c: dict, sel, row):
        """Vectorized :meth:`align` of entries ``sel``: (x, z, heading, heading cos, sin) of the
        patch origins."""
        th = row[2] - c["pdir"][sel]
        cs_, sn_ = np.cos(th), np.sin(th)
        pxz = c["pxz"][sel]
        px = row[0] - (cs_ * pxz[:, 0] + sn_ * pxz[:, 1])
        pz = row[1] - (cs_ * pxz[:, 1] - sn_ * pxz[:, 0])
        return px, pz, th, cs_, sn_
