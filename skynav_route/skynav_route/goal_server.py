# SPDX-License-Identifier: Apache-2.0
"""The FollowRoute and Home action servers, /skynav/follow_route and /skynav/home (docs/interfaces.md, "Driving:
teach, follow, home"), hosted by the route node: the rclpy glue around a goal's plan (skynav_route.goals).

A goal is refused before it drives (no command published) while the emergency stop is engaged, without a usable
map, for a bad request, or while another goal runs (BUSY). An accepted one sets the goal context of localize,
compass and warping (skynav_route.context, through skynav_core.peers, waiting up to `peer_timeout` s of steady
time), then the node drives it frame by frame (RouteNode.process) until it ends; a follow goal then sets localize
off the route again and records where it got to beside the map (skynav_core.route_progress, for `skynav follow
--resume`). A goal canceled before its execution began never drives (a client cancels a goal whose answer it did
not get: skynav_core.goals).
"""

from __future__ import annotations

from typing import Any

from rclpy.action import ActionServer, CancelResponse
from rclpy.task import Future

from skynav_core.actions import error_name
from skynav_core.maps import MapError
from skynav_core.names import FOLLOW_ROUTE_ACTION, HOME_ACTION
from skynav_core.namespaces import relative
from skynav_core.peers import PeerParameters
from skynav_core.route_progress import ProgressError, RouteProgress, now, write_progress
from skynav_msgs.action import FollowRoute, Home

from . import context, goals
from .controller import REACHED, RouteFollower
from .goals import CANCELED, SHUTDOWN, ActiveGoal, GoalPlan

BUSY_TEXT = 'another follow or home goal is running'


class GoalServer:
    """Serves FollowRoute and Home goals for the route node (`node`), which drives them."""

    def __init__(self, node: Any) -> None:
        self.node = node  # the RouteNode: its parameters, safety, and begin/finish of the goal it drives
        self.peers = PeerParameters(node, context.NODES)
        self.progress_unsaved = 0  # follow goals whose progress record could not be written beside the map
        self.servers = [
            ActionServer(node, kind, relative(name), execute_callback=execute, cancel_callback=self.on_cancel)
            for kind, name, execute in (
                (FollowRoute, FOLLOW_ROUTE_ACTION, self.execute_follow),
                (Home, HOME_ACTION, self.execute_home),
            )
        ]

    def plan(self, request: Any, codes: Any) -> GoalPlan | goals.Refusal:
        """Return how a FollowRoute or Home request is driven, or why it is refused."""
        node, log = self.node, self.node.get_logger()
        if node.safety.engaged:
            return codes.EMERGENCY_STOP, goals.emergency_refusal(node.safety.reason())
        try:
            route_map = goals.open_route_map(request.map_path, node.values['map'])
        except MapError as exc:
            return codes.NO_MAP, str(exc)
        if route_map.shape_source == 'nothing':
            log.info(f'{route_map.path}: no odometry or commands of the teach: steering on the home vectors alone')
        elif route_map.shape_source == 'commands':
            log.info(f"{route_map.path}: the route's shape by dead reckoning from the teach's velocity commands")
        planner = goals.plan_follow if codes is FollowRoute.Result else goals.plan_home
        return planner(request, route_map, node.values, node.settings)

    async def set_context(self, settings: context.Settings) -> None:
        """Give localize, compass and warping their parameters for a goal ({node: {name: value}}) and wait until they
        took them, unless configure_peers is off; a node that did not is logged, and the goal drives."""
        values = self.node.values
        if not values['configure_peers']:
            return
        parameters = {name: list(named.items()) for name, named in settings.items()}
        for name, reason in (await self.peers.set(parameters, values['peer_timeout'])).items():
            self.node.get_logger().warning(f'node {name} did not take its parameters for this goal: {reason}')

    async def run(self, kind: Any, handle: Any, plan: GoalPlan) -> tuple[str, ActiveGoal | None]:
        """Set the goal context, have the node drive the goal and return how it ended ('busy' if another one runs)."""
        node = self.node
        if node.active is not None:
            return 'busy', None
        goal = ActiveGoal(kind, handle, plan, Future())
        node.begin(goal)
        node.get_logger().info(f'time limit of the goal: {plan.time_limit.describe()}')
        if handle.is_cancel_requested:  # canceled before its execution began, when on_cancel found no active goal
            node.finish(CANCELED)
            return CANCELED, goal
        await self.set_context(plan.context.parameters())
        handle.publish_feedback(goals.first_feedback(kind))
        return await goal.done, goal

    async def execute_follow(self, handle: Any) -> FollowRoute.Result:
        """Drive along the route of a FollowRoute goal and record where it got to beside the map."""
        request, result, codes = handle.request, FollowRoute.Result(), FollowRoute.Result
        plan = self.plan(request, codes)
        if not isinstance(plan, GoalPlan):
            return self.refuse(handle, result, plan)
        outcome, active = await self.run(FollowRoute, handle, plan)
        if active is None:
            return self.refuse(handle, result, (codes.BUSY, BUSY_TEXT))
        if outcome != SHUTDOWN:
            await self.set_context(context.AFTER_FOLLOW)
        matched = plan.controller.matched if isinstance(plan.controller, RouteFollower) else -1
        result.reached_index = max(matched, -1)
        result = self.conclude(handle, result, outcome, active, codes, goals.unplaced(matched, request.start_index))
        ended = outcome if outcome in (REACHED, CANCELED) else error_name(result)
        route_map = plan.route_map
        self.record_progress(
            RouteProgress(
                route_map.path,
                route_map.count,
                request.start_index,
                plan.end,
                result.reached_index,
                ended,
                result.driven_length,
                now(),
            )
        )
        return result

    async def execute_home(self, handle: Any) -> Home.Result:
        """Drive to the place of the Home goal's snapshot."""
        result, codes = Home.Result(), Home.Result
        plan = self.plan(handle.request, codes)
        if not isinstance(plan, GoalPlan):
            return self.refuse(handle, result, plan)
        outcome, active = await self.run(Home, handle, plan)
        if active is None:
            return self.refuse(handle, result, (codes.BUSY, BUSY_TEXT))
        return self.conclude(handle, result, outcome, active, codes)

    def on_cancel(self, handle: Any) -> CancelResponse:
        """Accept a cancel: the robot stops at once."""
        active = self.node.active
        if active is not None and active.handle.goal_id == handle.goal_id:
            self.node.finish(CANCELED)
        return CancelResponse.ACCEPT

    def record_progress(self, progress: RouteProgress) -> None:
        """Store where a follow goal got to beside its map (skynav_core.route_progress) for `skynav follow --resume`;
        a record that cannot be written is logged and counted (progress_unsaved), and the goal's result stands."""
        try:
            write_progress(progress)
        except ProgressError as exc:
            self.progress_unsaved += 1
            self.node.get_logger().warning(f'{exc}: `skynav follow --resume` will not know where this goal ended')

    def refuse(self, handle: Any, result: Any, refusal: goals.Refusal) -> Any:
        """Abort a goal before it drove: no command is published (nothing moved)."""
        result.error_code, result.error_msg = refusal
        self.node.get_logger().warning(f'goal refused: {refusal[1]}')
        handle.abort()
        return result

    def conclude(
        self, handle: Any, result: Any, outcome: str, goal: ActiveGoal, codes: Any, lost: str | None = None
    ) -> Any:
        """Fill a finished goal's result and end its handle by the outcome (`lost`: the text of LOST, if not the
        usual one)."""
        result.driven_length = float(goal.driven)
        if outcome == REACHED:
            handle.succeed()
        elif outcome == CANCELED:
            handle.canceled()
        else:
            result.error_code, result.error_msg = goals.failure(
                outcome, codes, self.node.values['input_timeout'], goal.plan.time_limit, lost, goal.stop_reason
            )
            handle.abort()
        return result
