"""Centroid clustering of scan points (map frame) and the filter that keeps obstacle-like clusters.

The method the service is specified to use: each point, taken in scan order, joins the cluster
whose running centroid is nearest and within ``threshold``, otherwise it starts a new cluster;
afterwards clusters whose centroids lie within ``threshold`` of each other are merged. Two
refinements make it robust: a point also needs a neighbour in that cluster within ``gap`` (so
two obstacles a few centimetres apart are not bridged by their centroids), and the merge needs the
two clusters to touch within ``gap`` too. Distances to all clusters are computed at once (numpy);
the merge finds candidate pairs with a KD-tree and joins them as connected components (scipy).
"""
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
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
    the larger gap of the two touching points (``gaps``: one per point); transitively: the
    connected components of the graph of such pairs (scipy.sparse.csgraph), in the order of
    each component's first cluster."""
    if len(clusters) < 2:
        return clusters
    cent = np.array([pts[c].mean(axis=0) for c in clusters])
    trees = [cKDTree(pts[c]) for c in clusters]
    edges = []
    for a, b in cKDTree(cent).query_pairs(threshold):
        gb = gaps[clusters[b]]
        d, j = trees[a].query(pts[clusters[b]], distance_upper_bound=float(gaps.max()))
        ok = np.isfinite(d)
        if np.any(d[ok] <= np.maximum(gb[ok], gaps[clusters[a]][j[ok]])):
            edges.append((a, b))
    if not edges:
        return clusters
    n = len(clusters)
    a, b = np.array(edges, dtype=int).T
    _, label = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)),
                                    directed=False)
    groups = {}                  # by component, in the order of each one's first cluster
    for c, g in zip(clusters, label):
        groups.setdefault(g, []).append(c)
    return [np.sort(np.concatenate(g)) for g in groups.values()]
