"""Parameters: the segment planner's search (:class:`SearchParams`) apart from the policy of
whoever schedules many characters (:class:`CrowdPolicy`).

Defaults are the paper's where it gives one (Sung, Kovar and Gleicher 2005: n_m = 200,
k_m = 30, N_max = 1000, eps = 2 cm/s, 2 deg/s, 1/15 s/s); the others are this
implementation's, and the measured ones are explained in docs/decisions.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SearchParams", "CrowdPolicy"]


@dataclass
class SearchParams:
    """What one segment's planning does: seeds, the randomized search, the splice and the
    collision tests."""

    # randomized search (section 3.3)
    n_m: int = 200                 # perturbed pairs per iteration
    k_m: int = 30                  # pairs kept between iterations
    n_max: int = 1000              # iterations before giving up (warning, best pair used)
    eps: tuple = (0.02, 2.0, 1.0 / 15.0)   # per-frame adjustment tolerance: m/s, deg/s, s/s
    sweep: int = 100               # perturbations per iteration spent on every alternative of one clip
    sweep_pairs: int = 2000        # two-clip combinations scored per pair sweep (a random subset)
    splices_per_iteration: int = 3  # below-eps pairs spliced and collision-tested per iteration
    static_filter: float = 4.0     # pairs costing under this x eps are tested against static
    #                                obstacles before they may join the population (0: off) ...
    static_filter_slack: float = 0.1  # ... forgiving this much overlap (m)
    reseed_after: int = 20         # iterations after which a search whose splices collide makes new seeds
    hopeless_after: int = 20       # iterations after which a search still above ``hopeless_cost`` x eps,
    hopeless_cost: float = 4.0     # with no splice within eps, gives its segment up (0: never)
    retime_budget: int = 40        # colliding splices per search tried again at other durations (0: none)
    retime_tries: int = 12         # durations tried per colliding splice (nearest first)
    retime_step: int = 3           # frames between those durations
    split_resample: bool = True    # resample the two spliced parts separately (junction on a frame)
    # collision tests
    sample_step: int = 3           # frames between collision samples in seeds
    margin: float = 0.02           # extra clearance (m) in collision tests
    static_seed_margin: float = 0.0  # extra clearance (m) from obstacles in the seeds
    seed_margin: float = 0.0       # extra clearance (m) from planned characters in the seeds
    static_prefer: float = 0.12    # m of clearance from static obstacles a seed keeps when it can
    end_clearance: float = 0.65    # m from static obstacles a seed's edge must end (away from the goal); 0: off
    # greedy seeds (section 3.2)
    max_seed_edges: int = 80
    min_gain: float = 0.01         # metres (1 cm = 1 deg): smallest error decrease that counts
    min_gain_rate: float = 0.1     # metres per second of motion: smallest rate of decrease that counts
    approach_radius: float = 2.0   # metres from the goal where the seed starts to mind orientation
    facing_weight: float = 0.3     # metres per radian of facing away from the next way point
    lookahead_width: int = 12      # second-level edges per node in the seeds' two-edge lookahead
    reach_radius: float = 0.75     # a way point counts as reached within this distance (m)
    max_sidesteps: int = 6         # non-improving clear edges a seed may take per way point
    max_turns: int = 6             # edges a seed may take to turn towards its target when none gains on it
    backward_moving: bool = False  # backward seeds also keep clear of planned characters (at the
    #                                frames counted back from the window's middle); they always
    #                                keep clear of the static obstacles
    max_waits: int = 8             # idle clips a seed may insert to let a planned character pass
    stop_to_wait: bool = True      # a timed seed blocked at a walking hub stops on a node with idle clips to wait
    backward_idle: bool = False    # backward seeds may idle at the goal to spend surplus time
    carrot: float = 1.5            # seeds aim this far (m) along the way-point path ahead of themselves
    carrot_final: float = 3.0      # ... until the path's end is this close (m): then at the end itself
    route_lead: float = 1.0        # s: a seed keeping to a space-time route aims where the route is
    #                                this much later (runtime.crowd.planner.seeds)
    approach_point: float = 0.0    # m in front of a seat that the way points pass first, and last
    #                                when leaving one (0: off)
    fps: float = 30.0

    @property
    def alpha(self):
        """(a1 per radian, a2 per second) in metres, so that the cost is in m/s."""
        ep, et, es = self.eps
        return ep / np.radians(et), ep / es


@dataclass
class CrowdPolicy:
    """How a crowd's characters are scheduled around the segment planner: by the offline
    scheduler (:func:`runtime.crowd.scheduler.plan_scenario`) and, where it applies, the
    runtime World."""

    passes: int = 4                # planning passes; passes after the first repair failed characters
    bend_waypoints: bool = True    # way points bend round the characters who stand still (starts held
    #                                for characters not planned yet; runtime.crowd.planner.bend)
    still_static: bool = True      # characters who stay put for the whole of a segment are obstacles of
    #                                the search's static filter (runtime.crowd.planner.segment)
    space_time_seeds: bool = False  # seeds follow a route in space and time around the characters
    #                                planned before when a walk along the static route runs into one
    route_schedule: bool = True    # a seed along a space-time route keeps to its timing, not only
    #                                its turns (runtime.crowd.planner.seeds.GreedySeed)
    order: str = "file"            # planning order: "file", "longest", "shortest", "earliest", "endpoints",
    #                                "lattice" (runtime.crowd.scheduler.crowd_order)
    retry_n_max: int = 300         # search iterations of a further try at a segment that failed
    rung_budget: int | None = 900  # search iterations all the ladder's rungs of one segment may
    #                                spend together (runtime.crowd.goals); None: no bound
    #                                (the other start node, a later departure or arrival, repairs)
    relaxed_reserve: int = 60      # ... and when it is spent, search iterations the relaxed rung still
    #                                gets (per eps scale) before the goal is given up (0: none)
    depart_delays: tuple = (2.0, 4.0, 8.0)  # s an untimed goal's start is put off, in turn, when all
    #                                its motions collide (from a node where one can stand still) ...
    depart_within: float = 60.0    # ... and the first collision comes within this many s of the start
    depart_clear: bool = True      # ... first trying the whole seconds of waiting after which a
    #                                straight walk to the goal misses every planned character
    #                                (then 3 s more; the fixed delays when that is 0 s or never)
    depart_route: bool = False     # ... that walk following the segment's way points, not a straight line
    start_still: bool | None = None  # characters start on a node of their pose where they can stand
    #                                still and wait; False: the pose's most connected node (for "stand"
    #                                a walking hub); None: per character, still first when its first
    #                                goal's window opens more than ``wait_slack`` s after it could walk there
    wait_slack: float = 3.0        # s (see start_still)
    reserve_starts: str = "all"    # characters' starts held until they are planned: "none" (seated
    #                                starts while they need not leave), "needed" (any start while
    #                                it need not leave), "all" (any start, the whole scenario)
    reserve_goals: bool = False    # a last goal with a window is held from its opening until its
    #                                character is planned (runtime.crowd.scheduler.hold_goal)
    promote: bool = False          # a character that fails in the first pass where characters not
    #                                planned yet stand in its way has them planned first, then tries
    #                                again (runtime.crowd.scheduler._promote)
    hand_over: bool = True         # a repair may leave one displaced blocker failing in place of the
    #                                repaired character, when no worse off (once per character, and it
    #                                may not displace that one in turn; runtime.crowd.scheduler.repair)
    split_groups: bool = True      # interaction groups are planned apart, then merged (runtime.crowd.scheduler)
    workers: int | None = None     # processes planning groups at once (None: the cores; 1: in this process)
    reuse_motions: bool = True     # a motion found for one character is tried first for the next
    #                                with the same task relative to its start (motion_cache)
