"""Options of :mod:`laser_corners.localise`: one validated, frozen object, one set of defaults.

The field names are the vocabulary of the Python API, of YAML files (a ``localise:`` table)
and of the CLI's ``--set key=value``; a group by a dotted key (``icp.max_distance``,
``odometry.sigma_xy``, ``places.min_votes``, ``smooth.enabled``: :class:`SmoothOptions`,
``engine.gate_xy``: :class:`EngineOptions`). Defaults come from the sensors and robots (range
noise of centimetres, walking speed, rooms of a few metres), not from the scores of any log.
"""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from laser_corners.options import MountValue, Options
from laser_corners.registration.align import IcpOptions
from laser_corners.registration.odometry import OdometryNoise
from laser_corners.registration.place_index import PlaceOptions

__all__ = ["EngineOptions", "LocaliseOptions", "SmoothOptions"]


class EngineOptions(Options):
    """The engine's settings (:mod:`~laser_corners.localise.engine`): the ``engine`` group of
    :class:`LocaliseOptions` (``--set engine.gate_xy=0.5``, a YAML ``engine:`` table, the
    ROS 2 parameter ``engine.gate_xy``).

    Attributes
    ----------
    enabled : bool
        The online estimates come from the engine (:class:`~laser_corners.slam.Slam` in its
        frozen-map mode, ``localise.engine``): it tracks every scan against the map's
        keyframes near the pose and its own recent ones, closes loops into the map, and is
        placed by the fixes of the global search; the tracker decides when there is an
        estimate and re-places the engine where the two disagree by more than the gate. Off:
        the tracker's own poses (and for a ``map_server`` map, which has no keyframe scans).
    gate_xy : float
        The tracker and the engine disagree on a scan the map explains ("tracking") when they
        differ by more than this (m)...
    gate_yaw : float
        ... or by more than this (rad).
    gate_scans : int
        The map settles a disagreement: where it explains the scan at least as well at the
        engine's pose (its agreement there), the engine stands and the tracker follows it;
        the engine is re-placed at the tracker's pose only after this many tracked scans in a
        row that the map explains better at the tracker's (one scan the tracker slid on, a
        corridor or an ICP outlier, does not move it).

    Examples
    --------
    >>> EngineOptions().with_overrides(["gate_xy=0.5"]).gate_xy
    0.5
    """

    title: ClassVar[str] = "EngineOptions"
    what: ClassVar[str] = "option"

    enabled: bool = True
    gate_xy: float = Field(0.3, ge=0.0, le=100.0)
    gate_yaw: float = Field(0.05, ge=0.0, le=3.2)
    gate_scans: int = Field(3, ge=1, le=1000)


class SmoothOptions(Options):
    """The smoothed trajectory's settings (:mod:`~laser_corners.localise.smooth`): the
    ``smooth`` group of :class:`LocaliseOptions` (``--set smooth.enabled=false``, a YAML
    ``smooth:`` table, the ROS 2 parameter ``smooth.enabled``).

    Attributes
    ----------
    enabled : bool
        :func:`~laser_corners.localise.run_localise` also runs the SLAM front end over the
        scans and places every scan (before the first fix too) in one pose graph: the
        localiser's anchors on the SLAM's chain. Offline only (it uses the scans after each
        one); the CLI writes it as ``trajectory.tum`` and the causal estimates as
        ``online.tum``.
    anchor_travel : float
        One anchor per this travel (m, turns 0.5 m per radian): consecutive scans see the
        same part of the map and share its error. The SLAM's keyframe spacing.
    step_xy : float
        Noise (m) of one step of the SLAM chain between consecutive scans (scan matching).
    step_yaw : float
        Noise (rad) of one step of the SLAM chain.
    drift : float
        Growth of the chain's step noise per metre travelled (m/m; rad per metre and per
        radian turned: half of it): scan matching drifts about 1 % of the distance.

    Examples
    --------
    >>> SmoothOptions().with_overrides(["enabled=false"]).enabled
    False
    """

    title: ClassVar[str] = "SmoothOptions"
    what: ClassVar[str] = "option"

    enabled: bool = True
    anchor_travel: float = Field(0.4, ge=0.0, le=100.0)
    step_xy: float = Field(0.002, ge=1e-5, le=1.0)
    step_yaw: float = Field(0.001, ge=1e-6, le=1.0)
    drift: float = Field(0.01, ge=0.0, le=1.0)


class LocaliseOptions(Options):
    """Options of :class:`~laser_corners.localise.Localiser` (see ``docs/localise.md``)."""

    title: ClassVar[str] = "LocaliseOptions"
    what: ClassVar[str] = "option"
    section: ClassVar[str] = "localise"
    tuple_hints: ClassVar[dict[str, str]] = {"mount": "x,y,yaw"}

    mount: tuple[MountValue, MountValue, MountValue] | None = None
    """Base -> laser transform ``(x, y, yaw)``, overriding the recording's and the map's."""
    min_range: float = Field(0.1, ge=0.0, le=10.0)
    """Beams shorter than this (m) are not used."""
    max_range: float = Field(30.0, ge=0.5, le=1000.0)
    """Beams longer than this (m) are not used."""
    point_spacing: float = Field(0.1, ge=0.01, le=1.0)
    """Spacing (m) of the scan points kept for tracking (fewer points: cheaper ICP)."""
    map_spacing: float = Field(0.05, ge=0.01, le=1.0)
    """Voxel (m) to which the map's points are thinned (one point per voxel)."""
    icp: IcpOptions = IcpOptions(max_distance=0.3, iterations=15)
    """The ICP of the tracker and of the hypotheses against the map: a 0.3 m gate
    (``icp.max_distance``) and 15 iterations per scan (``icp.iterations``). Wider than the
    SLAM's (0.15 m, ``SlamOptions.icp``): the SLAM aligns to its own recent keyframes, the
    localiser to a map made another day (furniture moved, the map's own error)."""
    inlier_distance: float = Field(0.1, ge=0.01, le=1.0)
    """A scan point within this distance (m) of a map point agrees with the map."""
    odometry: OdometryNoise = OdometryNoise()
    """Odometry noise (``odometry.sigma_xy``: m per metre travelled, on 0.1 m more;
    ``odometry.sigma_yaw``: rad per radian turned plus per metre travelled): the ICP prior's
    weight and the growth of a lost track's window. The engine takes it too."""
    match_sigma: float = Field(0.03, ge=1e-3, le=1.0)
    """Noise (m) of one point-to-line residual, scaling the ICP information (covariance)."""
    track_agreement: float = Field(0.6, ge=0.0, le=1.0)
    """While tracking, a scan agreeing less than this with the map gives no estimate and
    counts towards lost."""
    track_drop: float = Field(0.25, ge=0.0, le=1.0)
    """A tracked scan agreeing this much less than the recent tracked scans (mean) gives no
    estimate either and counts towards lost: a kidnapped robot's scans rarely fit as well as
    before, even where a local search finds them a place."""
    lost_scans: int = Field(5, ge=1, le=1000)
    """This many scans in a row below ``track_agreement``: lost, back to global search."""
    global_every: int = Field(10, ge=1, le=1000)
    """While searching, an exhaustive search (the whole map, or a lost track's window) starts
    at most every n-th scan: the first on the first scan it is needed."""
    global_candidates: int = Field(16, ge=1, le=100)
    """Poses kept from one global search (best first, at least 1 m or 0.3 rad apart)."""
    global_resolution: float = Field(0.25, ge=0.05, le=2.0)
    """Position step (m) of the global search lattice (around the keyframe positions), to the
    nearest whole number of the likelihood grid's 0.1 m cells (0.25: 0.2 m)."""
    global_yaw_step: float = Field(0.035, ge=0.005, le=0.5)
    """Heading step (rad) of the global search."""
    global_reach: float = Field(3.0, ge=0.0, le=10.0)
    """The global search looks at positions within this distance (m) of a keyframe. A robot
    of a later visit drives where the mapping robot did not (across a room, along the other
    side of a hall) while its scans fit the map: aces' later visit, scans fitting 0.87-0.99 at
    1.6-10 m from every keyframe, never searched with 0.75 m. A few metres: a room's or a wide
    corridor's width; the cost grows with the positions (2-4x those of 0.75 m), paid only
    while searching."""
    max_hypotheses: int = Field(24, ge=1, le=500)
    """Hypotheses followed at most (the worst are dropped)."""
    hypothesis_agreement: float = Field(0.5, ge=0.0, le=1.0)
    """A hypothesis whose recent agreement falls below this is dropped."""
    fix_agreement: float = Field(0.7, ge=0.0, le=1.0)
    """Recent agreement a hypothesis needs to become the fix."""
    fix_margin: float = Field(0.04, ge=0.0, le=1.0)
    """Every other hypothesis must trail the winner by this much on average over the recent
    scans both were scored on (at least 3): its agreement lower plus its free-space conflict
    higher, shares of the scan's points and beams (``localise.hypotheses``)."""
    max_conflict: float = Field(0.2, ge=0.0, le=1.0)
    """Share of the tested beams (at most, on average over the recent scans) that may
    contradict the map's free space (end in space the map surely saw free, or see through
    one of its walls: ``localise.freespace``) at a hypothesis or a fix (and over the fix's
    history); above it the pose is refused (tracking: ``track_conflict``). Right poses of
    the later visits of aces and intel: median 0.04-0.07, 95th percentile 0.13-0.14 per
    scan."""
    max_loose_conflict: float = Field(0.4, ge=0.0, le=1.0)
    """The same on any evidence of the map (a cell crossed by one ray is free, one hit per
    three crossings is occupied): right poses of fr079 and intel median 0.17-0.19, 95th
    percentile 0.40-0.52 per scan, but look-alikes that the sure test passes (0.05-0.2)
    contradict it on 0.4-0.7 (intel's later visit)."""
    track_conflict: float = Field(0.5, ge=0.0, le=1.0)
    """While tracking, scans whose last ``conflict_scans`` contradict the map's free space on
    more than this share of the beams on average give no estimate and count towards lost
    (the track slid to a look-alike place, or the robot left the map). Higher than
    ``max_conflict``: where the map itself is wrong the right pose contradicts it for dozens
    of scans (fr079, a room drawn twice: 0.2-0.26; the last 80 scans of intel: 0.42-0.49),
    and losing a right track there costs more than a new fix there would."""
    conflict_scans: int = Field(10, ge=1, le=1000)
    """Window (scans) of the mean conflict of a tracked pose."""
    history_travel: float = Field(15.0, ge=0.0, le=1000.0)
    """Odometry travel (m) of the search's past scans (one per 0.2 m) that a fix is checked
    against: chained back from the winner by odometry, they must not contradict the map's
    free space (``track_conflict`` over ``conflict_scans``) either."""
    max_outside: float = Field(0.5, ge=0.0, le=1.0)
    """A scan with more of its beams ending where the map saw nothing is *outside* the map:
    no estimate, no fix attempt."""
    partly_outside: float = Field(0.15, ge=0.0, le=1.0)
    """A winner whose recent scans end outside the map more than this (mean share) needs
    ``outside_travel`` times ``fix_travel`` to become the fix."""
    outside_travel: float = Field(2.0, ge=1.0, le=20.0)
    """See ``partly_outside``."""
    fix_travel: float = Field(2.0, ge=0.0, le=100.0)
    """Odometry travel (m, turns counted as 0.5 m per radian) the winner must have survived,
    counting the search's past scans it explains (chained back by odometry,
    ``localise.history``): a pose proposed late is judged on the scans before it too."""
    fix_followed_travel: float = Field(0.5, ge=0.0, le=100.0)
    """Of that travel, how much the winner must have been followed since it was proposed
    (its rivals proposed meanwhile get scored against it)."""
    fix_scans: int = Field(10, ge=1, le=10000)
    """Scans the winner must have survived (the credited past scans included). A count of
    independent looks, whatever the scan rate: with ``fix_travel`` 2 m, 10 is one per
    0.2 m (aces' robot drove 0.17 m a scan, so 20 meant 3.4 m)."""
    recent_scans: int = Field(20, ge=3, le=1000)
    """Window (scans) of the recent agreement of a hypothesis."""
    distinct_xy: float = Field(0.5, ge=0.0, le=100.0)
    """Hypotheses closer than this (m) and ``distinct_yaw`` are one (the younger is merged)."""
    distinct_yaw: float = Field(0.2, ge=0.0, le=3.2)
    """See ``distinct_xy`` (rad)."""
    reacquire_xy: float = Field(3.0, ge=0.0, le=100.0)
    """After a lost track (not across an odometry or time jump), the search looks only inside
    the window of the dead-reckoned pose (``localise.window``) while its position's 3σ is
    within this (m) and its heading's within ``reacquire_yaw``; past either, the global search
    takes over. A few metres: a room or a corridor's stretch, where the few look-alikes left
    are told apart by the hypotheses' lead."""
    reacquire_yaw: float = Field(1.0, ge=0.0, le=3.2)
    """See ``reacquire_xy`` (rad). The heading's 3σ grows by ``odometry.sigma_yaw`` per metre
    and per radian (linearly, 3x that), so it reaches 1 rad after some 5 m of driving with
    turns, about when the position's reaches ``reacquire_xy``; a look-alike elsewhere is
    metres away, which the position limit excludes."""
    reacquire_travel: float = Field(1.0, ge=0.0, le=100.0)
    """Odometry travel (m, turns 0.5 m per radian) a winner inside the window must have
    survived (``fix_travel`` outside it): the window already excludes the far look-alikes
    that the global search's travel is there to tell apart."""
    odometry_jump: float = Field(1.0, ge=0.01, le=1000.0)
    """An odometry step (m, or rad) larger than this between two scans: the prediction is not
    trusted and the scan is searched for around the last pose with a wide prior."""
    time_jump: float = Field(5.0, ge=0.1, le=1e6)
    """A gap (s) between scan stamps larger than this is treated like an odometry jump."""
    give_up_travel: float = Field(150.0, ge=0.0, le=1e6)
    """Odometry travel (m) without any estimate (no fix, no accepted initial pose) after which
    :func:`~laser_corners.localise.run_localise` stops with "never found itself in this map"
    (a recording of another place); 0: never give up. A robot may start in a wing the map
    never saw: aces' later visit from 40 % of the log first meets the map after 58 m."""
    engine: EngineOptions = EngineOptions()
    """The engine (``localise.engine``): the online estimates come from the SLAM in its
    frozen-map mode, placed by the fixes (``engine.enabled``; re-placed past
    ``engine.gate_xy`` / ``engine.gate_yaw``)."""
    smooth: SmoothOptions = SmoothOptions()
    """The smoothed trajectory of :func:`~laser_corners.localise.run_localise`
    (``localise.smooth``; ``smooth.enabled=false``: the online estimates only)."""
    places: PlaceOptions = PlaceOptions(min_votes=1)
    """The place index: corner keypoints and descriptors of the map's keyframes, which propose
    global (re)localisation candidates in milliseconds (``places.enabled=false``: the
    exhaustive correlative search alone; see ``registration/place_index.py``). One corner
    may propose here (``min_votes`` 1, the SLAM's 2): every candidate is followed as a
    hypothesis for ``fix_travel`` and must beat every other one by ``fix_margin``, so a weak
    proposal costs an ICP per scan, never a wrong fix; on the shared logs it fixes sooner where
    corners are few (docs/benchmarks/relocalise.md)."""
