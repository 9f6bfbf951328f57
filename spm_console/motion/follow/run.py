"""A live-following run in the motion process: the same rules as every motion (homed first or
an explicit override, the run log, refusals logged), the loop of :mod:`.follow_loop`."""

from __future__ import annotations

from dataclasses import dataclass

from spm_console.config.schema import Profile
from spm_console.core.workspace.data import Workspace
from spm_console.devices.base import ServoBus
from spm_console.errors import RefusedError
from spm_console.motion.follow.loop import Follower, FollowStats
from spm_console.motion.follow.target_feed import TargetFeed
from spm_console.motion.logs.profile_record import wrist_digests
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.runs import Attach, RunContext, SampleCallback, refusals_logged
from spm_console.motion.segments import ExecutionResult
from spm_console.refusals import Refusal


@dataclass(frozen=True)
class FollowOutcome:
    """What a following run did, and how its re-planning went (None when it never started)."""

    execution: ExecutionResult
    stats: FollowStats | None


def run_follow(profile: Profile, bus: ServoBus, ws: Workspace, feed: TargetFeed, ctx: RunContext,
               on_sample: SampleCallback | None, attach: Attach, *, homed: bool,
               skip_homing: str = "", source: str | None = None) -> FollowOutcome:
    """Follow ``feed`` (see :mod:`spm_console.motion.follow.loop`) with the run log of kind
    ``follow``; refused unless homed or overridden with a reason."""
    what = {"kind": "follow", "source": source or ("live" if feed.live else "timed"),
            "targets": 0 if feed.timed is None else len(feed.timed.t_s)}
    log = RunLog.create("follow", profile.name, profile.digest(), [what], root=ctx.logs_root,
                        extra=ctx.meta(), wrist=wrist_digests(profile))
    log.on_finish = ctx.mcap_writer(profile)
    ex = Follower(profile, bus, workspace=ws, log=log, on_sample=on_sample, emulated=ctx.sim,
                  simulated_time=ctx.clock() is not None, **ctx.timing(live=feed.live))
    with refusals_logged(log):
        log.meta["homing"] = "done" if homed else f"skipped by the operator: {skip_homing}"
        if not homed and not skip_homing:
            raise RefusedError(Refusal.NOT_HOMED)
        attach(ex)
        result = ex.follow(feed)
        return FollowOutcome(result, ex.stats(feed))
