"""What SLAM and localisation share: scan points, ICP, correlative and keypoint global search.

Modules: :mod:`~.points` (a scan's points and line normals in the base frame), :mod:`~.align`
(point maps, point-to-line ICP, the share of a scan on a map), :mod:`~.correlative`
(likelihood grids and the exhaustive correlative search), :mod:`~.corners` (corner keypoints
with descriptors, queries chained by odometry), :mod:`~.corner_grid` (the map's corners
bucketed and grouped, the numba passes of a query), :mod:`~.place_index` (the map's corners
as an index: candidate poses for a query in milliseconds), :mod:`~.graph` (the pose graph's
gtsam vocabulary, a g2o graph's edges), :mod:`~.mapfolder` (the map folder, written whole and
read back) and :mod:`~.gridmap` (virtual keyframes of a map made by another package).
"""
