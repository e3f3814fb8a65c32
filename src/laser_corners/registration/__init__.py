"""What SLAM and localisation share: scan points, ICP, correlative and keypoint global search.

Modules: :mod:`~.points` (a scan's points and line normals in the base frame), :mod:`~.align`
(point maps, point-to-line ICP, the share of a scan on a map), :mod:`~.correlative`
(likelihood grids and the exhaustive correlative search), :mod:`~.place_index` (the map's
corner keypoints and descriptors: candidate poses for a query in milliseconds).
"""
