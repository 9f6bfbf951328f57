"""Picture of the workspace like the paper's Fig. 5: feasible nodes and the polytope P.

Three panels in θ space (deg): the boundary layer of feasible nodes with P's faces
(3D), singular / colliding nodes (3D), and a θ3 slice through home with P's
outline. matplotlib with the Agg backend (no display needed).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import ConvexHull

from spm_console.core.polytope.region import Region
from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]


def region_faces(region: Region) -> list[F]:
    """Polygons (each (k, 3), ordered) of P's faces, deg."""
    V = region.vertices()
    if len(V) < 4:
        return []
    hull = ConvexHull(V)
    faces: list[F] = []
    for a, b in zip(region.A, region.b, strict=True):
        on = np.abs(V @ a - b) < 1e-6 * max(1.0, abs(b))
        P = V[on]
        if len(P) < 3:
            continue
        c = P.mean(0)
        n = a / np.linalg.norm(a)
        e1 = P[0] - c
        e1 /= np.linalg.norm(e1) or 1.0
        e2 = np.cross(n, e1)
        ang = np.arctan2((P - c) @ e2, (P - c) @ e1)
        faces.append(P[np.argsort(ang)])
    del hull
    return faces


def plot_workspace(ws: Workspace, path: Path | str, title: str = "") -> None:
    """Write the figure to ``path`` (PNG)."""
    th = ws.theta_deg()
    feas = ws.feasible
    shell = feas & ~ndimage.binary_erosion(feas, structure=ndimage.generate_binary_structure(3, 1))
    fig = plt.figure(figsize=(15, 5), dpi=110)

    ax = fig.add_subplot(1, 3, 1, projection="3d")
    pts = th[shell]
    inP = ws.region.contains(pts)
    ax.scatter(*pts[~inP].T, s=2, c="tab:orange", alpha=0.6, label="feasible, outside P")
    ax.scatter(*pts[inP].T, s=1, c="tab:green", alpha=0.15, label="feasible, inside P")
    faces = region_faces(ws.region)
    if faces:
        # no autoscale: _axes3 sets the limits, and matplotlib's autoscale over ragged
        # faces (padded) overflows
        ax.add_collection3d(Poly3DCollection(faces, facecolor="tab:blue", alpha=0.25,
                                             edgecolor="k", linewidths=0.3), autolim=False)
    ax.set_title(f"P: {ws.region.halfspaces} half-spaces, {100 * ws.coverage():.1f} % of feasible")
    _axes3(ax, ws)
    ax.legend(loc="upper left", fontsize=7, markerscale=6)

    ax2 = fig.add_subplot(1, 3, 2, projection="3d")
    for mask, colour, label in ((ws.singular, "tab:red", "singular / unreached"),
                                (ws.colliding & ~ws.singular, "tab:purple", "links collide")):
        p = th[mask]
        if len(p):
            ax2.scatter(*p.T, s=2, c=colour, alpha=0.6, label=f"{label} ({len(p)})")
    ax2.set_title("infeasible nodes")
    _axes3(ax2, ws)
    ax2.legend(loc="upper left", fontsize=7, markerscale=6)

    ax3 = fig.add_subplot(1, 3, 3)
    k = ws.home_index[2]
    t3 = float(ws.axes_deg[2][k])
    img = ws.klass[:, :, k].T.astype(float)
    a0, a1 = ws.axes_deg[0], ws.axes_deg[1]
    h = 0.5 * ws.step_deg
    ax3.imshow(img, origin="lower", extent=(a0[0] - h, a0[-1] + h, a1[0] - h, a1[-1] + h),
               cmap=matplotlib.colors.ListedColormap(
                   ["#cfe8cf", "#e88", "#b9f", "#888", "#fc8"]), vmin=-0.5, vmax=4.5)
    g1, g2 = np.meshgrid(np.linspace(a0[0], a0[-1], 300), np.linspace(a1[0], a1[-1], 300))
    pts2 = np.stack([g1, g2, np.full_like(g1, t3)], -1)
    ax3.contour(g1, g2, ws.region.slack(pts2).min(-1), levels=[0.0], colors="tab:blue")
    ax3.set_xlabel("θ1 (deg)")
    ax3.set_ylabel("θ2 (deg)")
    ax3.set_title(f"slice θ3 = {t3:g}°: green feasible, red singular, violet collide; "
                  "blue = ∂P", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(str(path))
    plt.close(fig)


def _axes3(ax: object, ws: Workspace) -> None:
    lo, hi = ws.range_deg()
    for name in ("x", "y", "z"):
        getattr(ax, f"set_{name}lim")(lo, hi)
    ax.set_xlabel("θ1 (deg)")  # type: ignore[attr-defined]
    ax.set_ylabel("θ2 (deg)")  # type: ignore[attr-defined]
    ax.set_zlabel("θ3 (deg)")  # type: ignore[attr-defined]
