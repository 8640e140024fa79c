# SPDX-License-Identifier: GPL-3.0-or-later
"""Error of an indirect image against the Cycles truth over the covered pixels."""

from __future__ import annotations

import math

import numpy as np

from .demo import COVERED


class Errors:
    """Error metrics of indirect images against the truth over covered pixels.

    ``rmse``/``rel``: noise-corrected, sqrt(mean((x − a)(x − b))) with a, b the truth's two seeds
    (an unbiased estimate of the squared error against the noise-free truth: the truth's own noise
    is not charged to x; 0 if the estimate is negative). ``rmse_measured``/``rel_measured``: plain RMSE
    against the mean of the two seeds (includes the truth's noise in quadrature)."""

    def __init__(self, truth: dict, coverage: np.ndarray):
        self.mask = (truth["alpha"] > COVERED) & (coverage > COVERED)
        m = self.mask
        self.truth = truth["indirect"][m]
        self.seeds = ((truth["diffuse_a"] + truth["glossy_a"])[m], (truth["diffuse_b"] + truth["glossy_b"])[m])
        self.diffuse = (truth["diffuse_a"][m], truth["diffuse_b"][m])
        self.glossy = (truth["glossy_a"][m], truth["glossy_b"][m])
        self.mean = float(self.truth.mean())

    @staticmethod
    def _corrected(x, pair) -> float:
        return math.sqrt(max(float(np.mean((x - pair[0]) * (x - pair[1]))), 0.0))

    def __call__(self, diffuse, specular=None) -> dict:
        diffuse = np.asarray(diffuse, np.float64)[..., :3]
        total = diffuse if specular is None else diffuse + np.asarray(specular, np.float64)[..., :3]
        ours = total[self.mask]
        measured = float(np.sqrt(np.mean((ours - self.truth) ** 2)))
        rmse = self._corrected(ours, self.seeds)
        out = {"rmse": rmse, "rel": rmse / self.mean, "rmse_measured": measured, "rel_measured": measured / self.mean,
               "mean_ratio": float(ours.mean()) / self.mean, "finite": bool(np.all(np.isfinite(total)))}
        if specular is not None:
            d = diffuse[self.mask]
            sp = np.asarray(specular, np.float64)[..., :3][self.mask]
            out["rel_diffuse"] = self._corrected(d, self.diffuse) / float(np.mean(self.diffuse))
            out["rel_specular"] = self._corrected(sp, self.glossy) / float(np.mean(self.glossy))
            out["share_specular"] = float(np.mean(self.glossy)) / self.mean
        return out

    def by_region(self, image, material_index, names) -> dict:
        """Per material (of covered pixels): share of the noise-corrected squared error, its
        relative RMSE and mean ratio, and its share of the truth's light."""
        ours = np.asarray(image, np.float64)[..., :3][self.mask]
        labels = np.asarray(material_index)[self.mask]
        squared = (ours - self.seeds[0]) * (ours - self.seeds[1])
        total_squared = float(squared.sum())
        out = {}
        for index in np.unique(labels):
            m = labels == index
            truth = float(self.truth[m].mean())
            out[names[index] if index < len(names) else str(index)] = {
                "pixels": int(m.sum()), "error_share": float(squared[m].sum()) / total_squared,
                "rel": math.sqrt(max(float(squared[m].mean()), 0.0)) / truth if truth > 0 else float("nan"),
                "mean_ratio": float(ours[m].mean()) / truth if truth > 0 else float("nan"),
                "light_share": float(self.truth[m].sum()) / float(self.truth.sum())}
        return out
