"""Centroid clustering of scan points (map frame) and the filter that keeps obstacle-like clusters.

The method the service is specified to use: each point, taken in scan order, joins the cluster
whose running centroid is nearest and within ``threshold``, otherwise it starts a new cluster;
afterwards clusters whose centroids lie within ``threshold`` of each other are merged. Two
refinements make it robust: a point also needs a neighbour in that cluster within ``gap`` (so
two obstacles a few centimetres apart are not bridged by their centroids), and the merge needs the
two clusters to touch within ``gap`` too. Distances to all clusters are computed at once (numpy);
the merge uses a KD-tree (scipy) and a union-find over cluster pairs.
"""
import numpy as np
from scipy.spatial import cKDTree


def centroid_clusters(points, threshold, gap):
    """Cluster ``(N, 2)`` points [m] given in scan order. Returns a list of index arrays.

    ``gap`` [m] is a scalar or one value per point (the beams spread with range, so a far
    point may sit farther from its neighbour than a near one).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(pts)
    if n == 0:
        return []
    gaps = np.broadcast_to(np.asarray(gap, dtype=float), (n,))
    labels = np.empty(n, dtype=int)
    sums = np.zeros((n, 2))
    counts = np.zeros(n)
    last = np.zeros((n, 2))          # most recent member of each cluster
    k = 0
    for i in range(n):
        p = pts[i]
        if k:
            d = np.hypot(*(sums[:k] / counts[:k, None] - p).T)
            near = np.hypot(*(last[:k] - p).T) <= gaps[i]
            d[~near] = np.inf
            j = int(np.argmin(d))
            if d[j] <= threshold:
                labels[i] = j
                sums[j] += p
                counts[j] += 1
                last[j] = p
                continue
        labels[i] = k
        sums[k] = p
        counts[k] = 1
        last[k] = p
        k += 1
    return _merge([np.flatnonzero(labels == j) for j in range(k)], pts, threshold, gaps)


def _merge(clusters, pts, threshold, gaps):
    """Merge clusters whose centroids are within ``threshold`` and whose points touch within
    the larger gap of the two touching points (``gaps``: one per point); transitively, through a
    union-find over the pairs (centroids of the clusters found by the pass)."""
    if len(clusters) < 2:
        return clusters
    cent = np.array([pts[c].mean(axis=0) for c in clusters])
    parent = list(range(len(clusters)))

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    trees = [cKDTree(pts[c]) for c in clusters]
    for a, b in cKDTree(cent).query_pairs(threshold):
        if root(a) == root(b):
            continue
        gb = gaps[clusters[b]]
        d, j = trees[a].query(pts[clusters[b]], distance_upper_bound=float(gaps.max()))
        ok = np.isfinite(d)
        if np.any(d[ok] <= np.maximum(gb[ok], gaps[clusters[a]][j[ok]])):
            parent[root(a)] = root(b)
    groups = {}
    for i in range(len(clusters)):
        groups.setdefault(root(i), []).append(clusters[i])
    return [np.sort(np.concatenate(g)) for g in groups.values()]
