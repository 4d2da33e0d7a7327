#!/usr/bin/env python3
"""A per-point confidence histogram with matplotlib: normal_var (thesis Eq.
5.5) of bootstrap normals on a noisy cube, split at its 85th percentile as
in Table 5.2 (the points with the highest 15% of the variance are mostly on
the edges), with the angle error of each group against the exact normals.

Usage: /usr/bin/python3 examples/python/confidence_histogram.py [OUT.png]
Skipped (exit 0 with a message) when matplotlib is not installed
(apt-get install python3-matplotlib)."""
import sys

import numpy as np

import bootsurf

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("SKIP: matplotlib is not installed (apt-get install python3-matplotlib)")
    sys.exit(0)

out = sys.argv[1] if len(sys.argv) > 1 else "confidence_histogram.png"
cube = bootsurf.generate("cube", points=20000)
noisy = bootsurf.noise(cube, level=0.5)
fields, _ = bootsurf.normals(noisy, neighbors=30, bootstrap=30)
ev = bootsurf.evaluate(fields["normals"], cube["normals"], split=fields["normal_var"])
var = fields["normal_var"]
plt.figure(figsize=(7, 4))
plt.hist(np.log10(var[var > 0]), bins=60, color="#3b528b")
plt.axvline(np.log10(ev["split"]["threshold"]), color="#d62728",
            label="85th percentile (Table 5.2 split)")
plt.xlabel("log10 normal_var (rad^2, Eq. 5.5)")
plt.ylabel("points")
plt.title("high 15%%: mean angle error %.1f deg; low 85%%: %.1f deg"
          % (ev["normals"]["high"]["mean_deg"], ev["normals"]["low"]["mean_deg"]))
plt.legend()
plt.tight_layout()
plt.savefig(out, dpi=100)
print("->", out)
