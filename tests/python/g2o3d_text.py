"""A g2o SE(3) file parsed in plain Python (VERTEX_SE3:QUAT, EDGE_SE3:QUAT, FIX, PARAMS_SE3OFFSET,
EDGE_SE3_PRIOR, VERTEX_TRACKXYZ, EDGE_SE3_TRACKXYZ): the reference the C++ reader is checked
against. Quaternions (x, y, z, w), normalised; information rebuilt from the 21 (or 6) upper
entries; vertices in file order."""

from types import SimpleNamespace

import numpy as np


def _upper(values, n):
    m = np.zeros((n, n))
    m[np.triu_indices(n)] = values
    return m + np.triu(m, 1).T


def _unit(q):
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q)


def parse(path):
    """The file's records as arrays with the names of the old array reader (vertex_ids,
    quaternions, translations, fixed, edges, edge_quaternions, edge_translations, information,
    prior_*, point_*)."""
    v, e, p, pts, pe, fixed, params = [], [], [], [], [], set(), {}
    for line in open(path):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        tag, nums = f[0], f[1:]
        if tag == "VERTEX_SE3:QUAT":
            v.append((int(nums[0]), np.array(nums[1:4], float), _unit(nums[4:8])))
        elif tag == "EDGE_SE3:QUAT":
            e.append((int(nums[0]), int(nums[1]), np.array(nums[2:5], float), _unit(nums[5:9]),
                      _upper(np.array(nums[9:30], float), 6)))
        elif tag == "FIX":
            fixed.update(int(x) for x in nums)
        elif tag == "PARAMS_SE3OFFSET":
            params[int(nums[0])] = (np.array(nums[1:4], float), _unit(nums[4:8]))
        elif tag == "EDGE_SE3_PRIOR":
            p.append((int(nums[0]), np.array(nums[2:5], float), _unit(nums[5:9]), _upper(np.array(nums[9:30], float), 6)))
        elif tag == "VERTEX_TRACKXYZ":
            pts.append((int(nums[0]), np.array(nums[1:4], float)))
        elif tag == "EDGE_SE3_TRACKXYZ":
            t, q = params[int(nums[2])]
            pe.append((int(nums[0]), int(nums[1]), np.array(nums[3:6], float), _upper(np.array(nums[6:12], float), 3),
                       q, t))
    col = lambda rows, k, shape, dtype=float: np.array([r[k] for r in rows], dtype=dtype).reshape((len(rows),) + shape)
    return SimpleNamespace(
        vertex_ids=col(v, 0, (), np.int64), translations=col(v, 1, (3,)), quaternions=col(v, 2, (4,)),
        fixed=np.array([r[0] in fixed for r in v], bool),
        edges=np.array([(r[0], r[1]) for r in e], np.int64).reshape(-1, 2), edge_translations=col(e, 2, (3,)),
        edge_quaternions=col(e, 3, (4,)), information=col(e, 4, (6, 6)),
        prior_ids=col(p, 0, (), np.int64), prior_translations=col(p, 1, (3,)), prior_quaternions=col(p, 2, (4,)),
        prior_information=col(p, 3, (6, 6)),
        point_ids=col(pts, 0, (), np.int64), points=col(pts, 1, (3,)),
        point_fixed=np.array([r[0] in fixed for r in pts], bool),
        point_edges=np.array([(r[0], r[1]) for r in pe], np.int64).reshape(-1, 2), point_measurements=col(pe, 2, (3,)),
        point_information=col(pe, 3, (3, 3)), point_offset_quaternions=col(pe, 4, (4,)),
        point_offset_translations=col(pe, 5, (3,)))


def graph_arrays(graph, report=None):
    """A PoseGraph3D's content under the same names (poses in the order added), for comparing
    with ``parse`` or between two graphs."""
    ids, z, info = graph.pose_edges()
    pids, pz, pinfo = graph.pose_priors()
    qids, qz, qinfo, offsets = graph.point_edges()
    return SimpleNamespace(
        vertex_ids=graph.pose_ids, translations=graph.poses[:, :3], quaternions=graph.poses[:, 3:],
        fixed=np.array([graph.is_fixed(int(i)) for i in graph.pose_ids], bool),
        edges=ids, edge_translations=z[:, :3], edge_quaternions=z[:, 3:], information=info,
        prior_ids=pids, prior_translations=pz[:, :3], prior_quaternions=pz[:, 3:], prior_information=pinfo,
        point_ids=graph.point_ids, points=graph.points,
        point_fixed=np.array([graph.is_fixed(int(i)) for i in graph.point_ids], bool),
        point_edges=qids, point_measurements=qz, point_information=qinfo,
        point_offset_quaternions=offsets[:, 3:], point_offset_translations=offsets[:, :3], report=report)
