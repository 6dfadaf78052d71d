"""The coefficient file's LCM type (rt_monitor/lcmtypes/coefficients_t.lcm) as lcm-gen's Python codec.

The code is generated, not kept by hand: scripts/setup runs lcm-gen into dynid/export/_lcmtypes (gitignored), and the
C++ build generates the loader's header from the same .lcm. Imported from here, so that a tree without the set-up
fails in one line naming the fix (dynid.errors.SetupError).
"""

from __future__ import annotations

from ..errors import made_by_setup

with made_by_setup("dynid.export._lcmtypes", "lcm-gen's Python for rt_monitor/lcmtypes"):
    from ._lcmtypes.coefficients_t import coefficients_t

__all__ = ["coefficients_t"]
