"""Pose initialization of one frame (thesis §12.1, Fig. 12.8).

silhouettes → visual hull → D6I1D curve skeleton (border constraint for incomplete models)
→ data tree → weight normalization → AHA of the model tree into the data tree, rooted as
§12.1.1 prescribes → threshold T_d → betweenness constraints → part positions.

:class:`FrameEstimator` holds everything that does not change between frames (the model,
its :class:`~topopose.match.Matcher` precomputation, the hull's projection tables for the
capture and resolution); :func:`estimate_pose` is the one-frame convenience wrapper.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from topopose.errors import InputError
from topopose.frame.options import DEFAULT as DEFAULT_OPTIONS
from topopose.frame.options import EstimatorOptions
from topopose.frame.placement import (_touches_border, arm_keep, betweenness_by_lengths,
                                      fill_cavities, junction_position, off_axis_leaf,
                                      short_limb)
from topopose.frame.rules import (HEAD_FROM_HULL, JUNCTION_CORE, LEAF_AXIS, MATCHED_DISTANCE,
                                  PLACED_MISSING, PRUNE, SHORT_ARM, _rule_option, _spine_option,
                                  default_gate, default_tolerance)
from topopose.frame.thickness import (DEFAULT_THICKNESS_WEIGHT, THICKNESS, THICKNESS_REACH,
                                      matched_arc_cost, missing_cost, taxicab_radii,
                                      thickness_arc_cost, vertex_radii)
from topopose.pose.model import Model, load_model
from topopose.pose.pose import Pose

STAGES = ("hull", "thinning", "tree", "alignment")


class FrameError(Exception):
    """A frame that cannot be processed (reported as status "failed", the run goes on)."""


@dataclass
class FrameDetail:
    """Intermediate results of one frame (for pictures and debugging)."""

    volume: object = None          # topopose.Volume (the visual hull)
    skeleton: np.ndarray | None = None
    data: object = None            # data Tree (normalized weights)
    alignment: object = None


def _border_vertex(data):
    bv = data.diagnostics.get("border_vertex") if data.diagnostics else None
    if isinstance(bv, (list, tuple)):
        bv = bv[0] if len(bv) == 1 else None
    return bv


class FrameEstimator:
    """Pose initialization for the frames of one capture with one model (thesis §12.1).

    Builds once what every frame shares: the normalized, rooted model tree and its
    :class:`~topopose.match.Matcher`, and the visual-hull carver of the capture's grid.

    Parameters
    ----------
    cap : Capture
    model : Model or str
        A :class:`Model`, a built-in name or a TOML path.
    resolution : int
        Voxels along the longest side of the capture volume (thesis: 100 is the compromise).
    options : EstimatorOptions, optional
        Every option, grouped by stage (:class:`~topopose.frame.options.EstimatorOptions`,
        which documents each; default: the defaults).
    threshold : float, optional
        T_d; default the model's own (None in the model: 2, i.e. reject nothing).
    **flat
        Options changed by name: every field of the option groups, documented on
        :class:`~topopose.frame.options.EstimatorOptions`.
    """

    def __init__(self, cap, model="human", resolution=100, threshold=None,
                 options: EstimatorOptions | None = None, **flat):
        from topopose.match import Matcher
        from topopose.frame.confidence import min_confidence_for

        self.options = o = (options or DEFAULT_OPTIONS).with_(**flat)
        hu, th, a, pl, co, rec = (o.hull, o.thinning, o.alignment, o.placement, o.confidence,
                                  o.records)
        self.curves, self.leaves, self.arm_evidence = rec.curves, rec.leaves, rec.arm_evidence
        self.support, self.trim, self.centre = bool(rec.support), bool(rec.trim), bool(rec.centre)
        constraints, gate, min_confidence = a.constraints, co.gate, co.min_confidence
        self.min_share = float(co.min_share)
        # the fitted confidence knows upright subjects only (its head features look up): without
        # the coordinate constraints (acrobatic poses) the default gate is off — on, it rejected
        # 105 of the 198 frames of benchmarks/applications.py's acrobatic sequence, every
        # inverted one
        self.gate = ((default_gate(cap) and constraints) if gate is None else bool(gate))
        self.min_confidence = None if min_confidence is None else float(min_confidence)
        # per-part trust (pose/confidence.py judge_frame, DROP_PARTS): None/True on, False off
        self.part_trust = co.part_trust is not False
        # head doubt (pose/confidence.py head_doubt): None/True an unmatched head, "any" any
        # head, False off
        self.head_doubt = True if co.head_doubt is None else co.head_doubt

        self.cap = cap
        self.model: Model = load_model(model, constraints=constraints)
        from topopose.frame.confidence import GATE
        rule = GATE if co.gate_rule is None else co.gate_rule
        self.gate_rule = rule if self.gate and rule and self.model.name in rule.models else None
        if self.gate_rule is not None:
            self.support = self.curves = True     # the gate reads the silhouette support and
            #                                       the feet's curves
        if self.min_confidence is None and self.model.name == "human":
            # calibrated for the human model only, per number of cameras
            self.min_confidence = min_confidence_for(len(cap.cameras))
        self.resolution = int(resolution)
        if self.resolution < 8:
            raise InputError(f"--resolution: {resolution} is too small (at least 8 voxels)")
        self.threshold = (float(threshold) if threshold is not None
                          else (self.model.threshold if self.model.threshold is not None else 2.0))
        self.betweenness = a.betweenness
        self.relation = a.relation
        self.max_missing = int(a.max_missing)
        self.thinning = th.method
        self.tolerance = default_tolerance(cap) if hu.tolerance is None else int(hu.tolerance)
        self.fill = bool(hu.fill)
        self.refocus = bool(hu.refocus)
        from topopose.hull.hull import MASK_RESOLUTION
        self.mask_resolution = (MASK_RESOLUTION if hu.mask_resolution is True
                                else (hu.mask_resolution or None))
        self.repair = 1 if hu.repair is None else int(hu.repair)
        self.pattern = self.model.pattern()
        junction_centroid = pl.junction_centroid
        if junction_centroid is None:
            junction_centroid = self.model.complete
        adj = self.model.tree.adjacency()
        self.junctions = ({p for p in self.model.parts if len(adj[p]) > 1}
                          if junction_centroid else set())
        self.junction_core = (JUNCTION_CORE.get(self.model.name, False)
                              if pl.junction_core is None else bool(pl.junction_core))
        self.up = np.asarray(cap.up_vector, dtype=float)
        self.matcher = Matcher(self.pattern, method="aha", cut=False, up=self.up,
                               keep_junctions=a.keep_junctions is not False)
        self.warmup = None      # first run: the helper process of topopose.batch.warmup.start_warmup
        self.thickness_profile = (THICKNESS.get(self.model.name) if a.thickness_profile is None
                                  else dict(a.thickness_profile))
        thickness, prune = a.thickness, th.prune
        if thickness is None:
            thickness = DEFAULT_THICKNESS_WEIGHT
        self.thickness = float(thickness) if self.thickness_profile else 0.0
        self.thickness_reach = max(1, round(THICKNESS_REACH * self.resolution))
        if prune is None:
            prune = PRUNE.get(self.model.name, 0.0)
        self.prune = float(prune)
        nb = [p for p in self.model.neighbours(self.model.root) if p in self.junctions
              or len(adj[p]) > 1]
        self._root_arc = nb[0] if nb else None
        # a leaf that must continue the body axis (LEAF_AXIS): (leaf, junction, axis end, cos)
        rule = LEAF_AXIS.get(self.model.name)
        cos = (rule[3] if rule else 0.0) if pl.leaf_axis is None else float(pl.leaf_axis)
        self.leaf_axis = (*rule[:3], cos) if rule and cos else None
        self.tip_fraction = float(pl.tip_fraction)
        # the head from the hull's highest thick point (pose/tips.py), for upright subjects
        rule = HEAD_FROM_HULL.get(self.model.name)
        frac = ((rule[2] if rule and any(c.kind == "above" and rule[0] in c.parts
                                          for c in self.model.constraints) else 0.0)
                if pl.head_from_hull is None else float(pl.head_from_hull))
        self.head_from_hull = (rule[0], rule[1], frac) if rule and frac > 0 else None
        # leaf parts placed where their branch leaves the hull (pose/tips.py)
        stems = set(pl.tips or ())
        self.tips = [p for p in self.model.parts if len(adj[p]) == 1 and self.model.complete
                     and p.rstrip("_0123456789") in stems]
        # tips prolonged away from an anchor part (TIP_ANCHOR), where the hull does not place them
        from topopose.frame.tips import TIP_ANCHOR
        tip_anchor = pl.tip_anchor
        if isinstance(tip_anchor, dict):
            self.tip_anchor = dict(tip_anchor)
        elif tip_anchor is None or tip_anchor is True:
            placed = {self.head_from_hull[0]} if self.head_from_hull else set()
            self.tip_anchor = {p: r for p, r in TIP_ANCHOR.get(self.model.name, {}).items()
                               if p not in placed}
        else:
            self.tip_anchor = {}
        self.spine = _spine_option(self.model, pl.spine)
        self.matched_distance = (MATCHED_DISTANCE.get(self.model.name, False)
                                 if a.matched_distance is None else bool(a.matched_distance))
        from topopose.frame.anatomy import CROTCH_DROP, TORSO_ON_TRUNK, TRUNK_BLEND
        self.trunk = _rule_option(self.model, TORSO_ON_TRUNK, pl.trunk, default=True)
        trunk_blend = pl.trunk_blend
        if isinstance(trunk_blend, (int, float)) and not isinstance(trunk_blend, bool):
            rule = TRUNK_BLEND.get(self.model.name) if self.model.complete else None
            self.trunk_blend = (*rule[:4], float(trunk_blend)) if rule and trunk_blend else None
        else:
            self.trunk_blend = _rule_option(self.model, TRUNK_BLEND, trunk_blend, default=True)
        self.crotch_drop = _rule_option(self.model, CROTCH_DROP, pl.crotch_drop, default=True)
        self.placed_missing = (PLACED_MISSING.get(self.model.name, False)
                               if a.placed_missing is None else bool(a.placed_missing))
        # a hand whose branch ends at the elbow (SHORT_ARM): (hands, torso, crotch, feet, ratio)
        rule = SHORT_ARM.get(self.model.name) if self.model.complete else None
        ratio = (rule[4] if rule else 0.0) if pl.short_arm is None else float(pl.short_arm)
        self.short_arm = (*rule[:4], ratio) if rule and ratio > 0 else None
        # a hand next to the trunk's core (HAND_ON_TRUNK): (hands, core, reach)
        from topopose.frame.anatomy import HAND_ON_TRUNK
        rule = HAND_ON_TRUNK.get(self.model.name) if self.model.complete else None
        reach = (rule[2] if rule else 0.0) if pl.hand_trunk is None else float(pl.hand_trunk)
        self.hand_trunk = (*rule[:2], reach) if rule and reach > 0 else None
        # the head from the hull holds a head-sized ball (tips.HEAD_BALL): (ball, reach)
        from topopose.frame.tips import HEAD_BALL
        rule = HEAD_BALL.get(self.model.name)
        ball = ((rule[0] if rule and len(cap.cameras) >= rule[3] else 0.0)
                if pl.head_ball is None else float(pl.head_ball))
        self.head_ball = ((ball, *(rule[1:3] if rule else (1.5, 1.5))) if ball > 0 else None)
        # without coordinate constraints: the head from the hull along the body's own axis
        # (tips.HEAD_AXIS): (head, anchor, lower end, min_fraction, max_shift)
        from topopose.frame.tips import HEAD_AXIS
        rule = HEAD_AXIS.get(self.model.name) if self.model.complete else None
        on = (not any(c.kind == "above" and rule[0] in c.parts for c in self.model.constraints)
              if pl.head_axis is None and rule else bool(pl.head_axis))
        self.head_axis = tuple(rule) if rule and on else None

    def arc_cost(self, vol, data, radii=None):
        """The thickness arc cost of this frame (:func:`thickness_arc_cost`), or None when off.
        ``radii``: :func:`taxicab_radii` of ``vol`` if already computed."""
        if not self.thickness:
            return None
        return thickness_arc_cost(vertex_radii(vol, data, self.thickness_reach, radii),
                                  self.thickness_profile, self.thickness,
                                  root=self.model.root, root_arc=self._root_arc)

    # ------------------------------------------------------------------ stages
    def hull(self, frame):
        """Visual hull of ``frame`` on the capture's grid.

        :func:`topopose.visual_hull` caches the grid's projection tables on the capture, so
        they are built once per capture and resolution (per process). With ``tolerance > 0``
        and ``repair ≥ 0`` it is the consensus hull (``visual_hull(..., consensus=repair)``:
        the strict and the tolerant hull from one carve, see
        :func:`topopose.hull.hull.consensus_hull_labels`).
        """
        from topopose.hull import visual_hull

        consensus = self.repair if self.tolerance > 0 and self.repair >= 0 else None
        masks = None
        factors = self.mask_factors()
        if factors is not None:         # read at the resolution the grid needs
            from topopose.capture.io import reduce_masks
            masks = reduce_masks(self.cap.silhouettes(frame), factors)
        elif not self.refocus:
            # each silhouette's bounding box once, for the hull, the support and the trim
            from topopose.geometry.masks import boxed
            from topopose.hull import uses_soft_fusion
            if not uses_soft_fusion(self.cap):
                masks = [boxed(m) for m in self.cap.silhouettes(frame)]
        if self.support or self.trim or self.centre:   # the silhouettes the hull is carved from
            from topopose.hull import uses_soft_fusion
            from topopose.frame.support import compared_views
            self._silhouettes = None
            if not uses_soft_fusion(self.cap):
                if masks is None:
                    masks = self.cap.silhouettes(frame)
                self._silhouettes = compared_views(self.cap.cameras, masks)
        vol = visual_hull(self.cap, frame, resolution=self.resolution, tolerance=self.tolerance,
                          consensus=consensus, refocus=self.refocus, masks=masks)
        if (self.support or self.trim or self.centre) and self._silhouettes is None:  # cached
            from topopose.capture.background import foreground_maps, scaled_camera
            p = self.cap.options["silhouettes"]
            cut = int(255 * float(p.get("cut", 0.5)))
            self._silhouettes = ([scaled_camera(c, float(p["scale"])) for c in self.cap.cameras],
                                 [q > cut for q in foreground_maps(self.cap, frame)])
        return vol

    def mask_factors(self):
        """Per camera, the reduction of the masks that the fixed grid's silhouette test needs
        (:func:`topopose.hull.hull.mask_factors` with :attr:`mask_resolution`), computed once
        (it fits the capture volume); None: masks at full resolution (the option off — the
        default —, refocused or zone grids, soft fusion, or no volume to fit)."""
        if "_factors" not in self.__dict__:
            from topopose.hull import uses_soft_fusion
            from topopose.hull.hull import _person_grid, fitted_grid, grid_for_box, mask_factors

            self._factors = None
            cap = self.cap
            if (self.mask_resolution is not None and not self.refocus
                    and not uses_soft_fusion(cap) and not _person_grid(cap)):
                try:
                    if cap.volume is not None:
                        grid = grid_for_box(*cap.volume, self.resolution, margin=False)
                    else:
                        grid = fitted_grid(cap, self.tolerance, self.resolution)
                except InputError:        # reported by the frame that needs the volume
                    return None
                f = mask_factors(cap.cameras, *grid, self.mask_resolution)
                self._factors = f if max(f) > 1 else None
        return self._factors

    def estimate(self, frame, detail: bool = False):
        """Pose of one frame; never raises for a frame-level problem (status "failed").

        Returns a :class:`Pose`, or ``(Pose, FrameDetail)`` when ``detail`` is true.
        """
        name = self.cap.frame_name(frame)
        timings = {}
        det = FrameDetail()
        t_all = time.perf_counter()
        got = self._stages(name, timings, det, t_all)
        if isinstance(got, Pose):
            return (got, det) if detail else got
        vol, n_vox, skel, data, sq, al, thick, arc_cost, radii, unordered = got

        # T_d applies to the length distance of §12.1.1; the thickness term only chooses the
        # alignment (see THICKNESS for the measurement)
        t0 = time.perf_counter()       # "placement": parts, judgement and curves of the frame
        dist = float(al.distance) - thick
        parts, on_skeleton, missing, rules, edt, sk_vox = self._place(vol, skel, data, al, sq,
                                                                      unordered)
        dropped, short, from_hull, on_core, on_trunk, diag_spine, detect_parts = (
            rules[k] for k in ("dropped", "short", "from_hull", "on_core", "on_trunk",
                               "diag_spine", "detect_parts"))
        status, error, extra, parts, mcost = self._judge(vol, n_vox, data, al, dist, thick,
                                                         radii, parts, on_skeleton, missing,
                                                         unordered)
        diag = {"model": self.model.name, "resolution": self.resolution,
                "hull_tolerance": self.tolerance, "hull_voxels": n_vox,
                "skeleton_voxels": int(data.diagnostics.get("n_voxels", -1)),
                "data_vertices": data.n_vertices, "missing": missing, **extra}
        if vol.diagnostics.get("grid") == "beyond":    # carved on a grid of its own
            diag["hull_grid"] = "beyond"
        if arc_cost is not None:
            diag["thickness_cost"] = round(thick, 6)
        diag["missing_cost"] = round(mcost, 6)
        if self.prune > 0:
            diag["pruned_bumps"] = len(data.diagnostics.get("pruned_bumps", ()))
        if from_hull:
            diag["from_hull"] = from_hull
        if dropped:
            diag["off_axis"] = dropped
        if short:
            diag["short_arm"] = short
        if on_core:
            diag["hand_on_trunk"] = on_core
        if on_trunk:
            diag["on_trunk"] = self.trunk[0]
        if self.spine:
            diag["spine_shift"] = diag_spine
        detect_parts = {p: x for p, x in detect_parts.items() if parts.get(p) is not None}
        if detect_parts:
            # the crotch before the drop (pose/anatomy.py CROTCH_DROP): the pelvis, what the
            # pose descriptions compare (§13.3.2.1, topopose.apps.detect.description_parts)
            diag["detect_parts"] = detect_parts
        if unordered:
            diag["betweenness_unsatisfied"] = sorted(set(unordered), key=unordered.index)
        if self.curves:
            self._record(diag, vol, skel, data, al, parts, on_skeleton,
                         short + on_core + ([extra["untrusted"]] if extra.get("untrusted")
                                            else []), edt, sk_vox, timings)
        if self.leaves:      # candidates for a misplaced numbered part (pose.track)
            from topopose.frame.tips import free_leaves
            diag["free_leaves"] = free_leaves(data, al.mapping)
        if self.gate_rule is not None:   # the gate (topopose.frame.confidence.GateOptions)
            from topopose.frame.confidence import gate_decision
            status, error = gate_decision(status, error, diag, self.gate_rule,
                                          sum(x is None for x in parts.values()), self.max_missing,
                                          self.up)
        timings["placement"] = (time.perf_counter() - t0) * 1e3
        timings["total"] = (time.perf_counter() - t_all) * 1e3
        pose = Pose(name, status, dist, parts, error, timings, diag)
        return (pose, det) if detail else pose

    def _stages(self, name, timings, det, t_all):
        """Hull → thinning → data tree → alignment of one frame (§12.1): ``(vol, n_vox, skel,
        data, sq, al, thick, arc_cost, radii, unordered)``, or the failed :class:`Pose`."""
        from topopose.skeleton import data_tree
        from topopose.topology import thin

        stage = "hull"
        try:
            t0 = time.perf_counter()
            vol = self.hull(name)
            timings["hull"] = (time.perf_counter() - t0) * 1e3
            det.volume = vol
            n_vox = vol.diagnostics.get("voxels")
            if n_vox is None:
                n_vox = int(np.count_nonzero(vol.data))
            if n_vox == 0:
                raise FrameError("empty visual hull: no voxel lies inside every silhouette "
                                 "(empty silhouette, or the subject is outside the capture volume)")
            touches = vol.diagnostics.get("touches_border")
            if touches is None:
                touches = _touches_border(vol.data)
            if self.model.complete and touches:
                raise FrameError("the subject crosses the border of the capture volume "
                                 "(visual hull touches the grid side); enlarge [capture.volume] "
                                 "or use an incomplete model")
            stage = "thinning"
            if self.fill:
                t0 = time.perf_counter()
                vol = fill_cavities(vol)
                det.volume = vol
                timings["fill"] = (time.perf_counter() - t0) * 1e3
            t0 = time.perf_counter()
            keep = None if self.model.complete else arm_keep(vol)
            if self.warmup is not None:
                self.warmup.wait_tables()
            skel = thin(vol, method=self.thinning, keep=keep)
            timings["thinning"] = (time.perf_counter() - t0) * 1e3
            det.skeleton = skel
            stage = "tree"
            if self.warmup is not None:       # its tree and alignment kernels are now cached
                self.warmup.wait_all()
                self.warmup = None
            t0 = time.perf_counter()
            # incomplete model: the skeleton end pinned where the infinite limb leaves the
            # grid is the border vertex (a mask, not "grid": fingertips touching the grid
            # side must not become infinite limbs too)
            sq = None
            if self.prune > 0:         # bumps of the surface are no limbs (skeleton.prune)
                from topopose.skeleton.prune import prune_bumps
                if self.spine or self.head_from_hull is not None:
                    # the distance transform the placement needs anyway gives the ball radii
                    from topopose.frame.tips import hull_box, squared_distances
                    sq = squared_distances(vol.data, hull_box(vol))
                skel, data, _ = prune_bumps(skel, vol.data, self.prune, vol.origin,
                                            vol.voxel_size,
                                            border=None if self.model.complete else keep,
                                            squared=sq)
                det.skeleton = skel
            else:
                data = data_tree(skel, origin=vol.origin, voxel_size=vol.voxel_size,
                                 border=None if self.model.complete else keep)
            data_root = None
            if not self.model.complete:
                data_root = _border_vertex(data)
                if data_root is None:
                    raise FrameError("no skeleton branch crosses the capture border, but the "
                                     f"model {self.model.name!r} is incomplete (its "
                                     f"{self.model.infinite_edge[0]!r} limb must leave the volume)")
            data = data.normalized()
            data.root = data_root
            timings["tree"] = (time.perf_counter() - t0) * 1e3
            det.data = data
            stage = "alignment"
            t0 = time.perf_counter()
            # once a frame: the thickness term and judge_frame (which computes it when None)
            radii = taxicab_radii(vol) if self.thickness else None
            arc_cost = self.arc_cost(vol, data, radii)
            al = self.matcher.align(data, data_root=data_root, arc_cost=arc_cost)
            thick = matched_arc_cost(al, arc_cost)
            if self.matcher.contractible is not None:
                # keep_junctions: the trunk contracted only when that alone passes T_d
                def judged(a, t):
                    return a.distance - t - (missing_cost(self.pattern, a)
                                             if self.matched_distance else 0.0)
                if judged(al, thick) > self.threshold:
                    al2 = self.matcher.contractible.align(data, data_root=data_root,
                                                          arc_cost=arc_cost)
                    thick2 = matched_arc_cost(al2, arc_cost)
                    if judged(al2, thick2) <= self.threshold:
                        al, thick = al2, thick2
                        al.diagnostics["junctions_contracted"] = True
            unordered = []
            if self.betweenness:
                for c in self.model.constraints:
                    if c.kind == "between":
                        if self.relation is not None:
                            from topopose.match.tree import Constraint
                            c = Constraint(c.kind, c.parts, c.axis, self.relation)
                        al = betweenness_by_lengths(al, self.pattern, data, c)
                        if (al.diagnostics or {}).get("betweenness") == "unsatisfied":
                            # no co-optimal order satisfies it: those parts stay unplaced, a
                            # partial matching the method rejects (§13.2.2.2, R_b)
                            unordered.extend(c.parts)
                            al.diagnostics.pop("betweenness", None)
            timings["alignment"] = (time.perf_counter() - t0) * 1e3
            det.alignment = al
        except FrameError as exc:
            pose = self._failed(name, f"{stage}: {exc}", timings, t_all)
            return pose
        except InputError as exc:
            pose = self._failed(name, f"{stage}: {exc}", timings, t_all)
            return pose
        except Exception as exc:  # a frame never stops a run
            pose = self._failed(name, f"{stage}: {type(exc).__name__}: {exc}", timings, t_all)
            return pose
        return vol, n_vox, skel, data, sq, al, thick, arc_cost, radii, unordered

    def _place(self, vol, skel, data, al, sq, unordered):
        """The parts' positions from the alignment and the placement rules; returns ``(parts,
        on_skeleton, missing, rules, edt, sk_vox)``, ``rules`` the diagnostics of the rules
        that moved or dropped parts (``dropped``, ``short``, ``from_hull``, ``on_core``,
        ``on_trunk``, ``diag_spine``, ``detect_parts``)."""
        from topopose.frame.tips import hull_box, skeleton_voxels
        box = hull_box(vol)
        sk_vox = skeleton_voxels(skel, box)     # the skeleton's voxels, once a frame
        parts = {}
        for p in self.model.parts:
            v = al.mapping.get(p)
            pos = None if v is None else data.positions.get(v)
            if pos is not None and p in self.junctions:
                pos = junction_position(al, data, p, v, leaves=not self.junction_core)
            parts[p] = None if pos is None or p in unordered else np.asarray(pos, dtype=float)
        dropped = []
        if (self.leaf_axis is not None and all(x is not None for x in parts.values())
                and off_axis_leaf(data, al.mapping, *self.leaf_axis)):
            dropped.append(self.leaf_axis[0])
            parts[self.leaf_axis[0]] = None
        short = []
        if self.short_arm is not None and all(x is not None for x in parts.values()):
            p = short_limb(data, al.mapping, *self.short_arm)
            if p is not None:
                short.append(p)
                parts[p] = None
        on_skeleton = dict(parts)      # the skeleton curves end at the branch ends
        if self.tips:
            from topopose.frame.tips import extremity_tips
            for p, x in extremity_tips(vol, skel, data, al.mapping, self.tips,
                                          voxels=sk_vox, anchors=self.tip_anchor).items():
                if parts.get(p) is not None:
                    parts[p] = (x if self.tip_fraction == 1.0
                                else parts[p] + self.tip_fraction * (x - parts[p]))
        edt = None
        if self.spine or self.head_from_hull is not None or self.hand_trunk is not None:
            from topopose.frame.tips import inscribed_distances      # inscribed radii, once a frame
            edt = inscribed_distances(vol.data, box, sq)
        detect_parts = {}
        if self.spine:      # the spine lies behind the medial axis (pose/anatomy.py)
            parts, diag_spine, detect_parts = self.spine_parts(vol, skel, data, al, parts, edt,
                                                               sk_vox)
        missing = [p for p, x in parts.items() if x is None]   # by the alignment: the status
        from_hull = []
        if self.head_from_hull is not None:
            from topopose.frame.tips import head_from_hull
            head, anchor, frac = self.head_from_hull
            x = head_from_hull(vol, self.up, parts.get(anchor), frac, edt=edt,
                               ball=self.head_ball)
            if x is not None:
                parts[head] = x
                from_hull.append(head)
        if self.head_axis is not None:       # no "up" for the head: the body's axis instead
            from topopose.frame.tips import head_along_axis
            x = head_along_axis(vol, parts, self.head_axis, edt, self.head_ball)
            if x is not None:
                parts[self.head_axis[0]] = x
                from_hull.append(self.head_axis[0])
        on_core = []      # after the head from the hull: a head it placed counts as placed
        if self.hand_trunk is not None and all(x is not None for x in parts.values()):
            from topopose.frame.anatomy import hand_on_trunk
            p = hand_on_trunk(parts, self.hand_trunk, vol, edt)
            if p is not None:
                on_core.append(p)
                parts[p] = None
                on_skeleton[p] = None      # no curve to the elbow either
                missing.append(p)
        on_trunk = False
        if self.trunk is not None:       # a torso slid down to the crotch (pose/anatomy.py)
            from topopose.frame.anatomy import torso_on_trunk
            parts, on_trunk = torso_on_trunk(parts, self.trunk)
        if self.trunk_blend is not None:     # arms on the chest pull the junction forward
            from topopose.frame.anatomy import trunk_blend
            parts = trunk_blend(parts, self.trunk_blend)
        rules = dict(dropped=dropped, short=short, from_hull=from_hull, on_core=on_core,
                     on_trunk=on_trunk, diag_spine=diag_spine if self.spine else None,
                     detect_parts=detect_parts)
        return parts, on_skeleton, missing, rules, edt, sk_vox


    def _judge(self, vol, n_vox, data, al, dist, thick, radii, parts, on_skeleton, missing,
               unordered):
        """The frame's status (T_d, unmatched parts, the confidence gate): ``(status, error,
        extra, parts, mcost)``, ``extra`` the confidence diagnostics; per-part trust may unplace
        one part (in ``parts`` and ``on_skeleton``)."""
        status, error = "matched", None
        mcost = missing_cost(self.pattern, al)
        # T_d judges what the matched parts cost (MATCHED_DISTANCE): a missing limb is a right
        # frame (§13.2.2), its deleted arm's own cost no reason to reject it
        judged = dist - mcost if self.matched_distance else dist
        if not math.isfinite(dist) or judged > self.threshold:
            status = "rejected"
            error = f"AHA distance {dist:.3f} above threshold T_d = {self.threshold:g}"
            if judged != dist:
                error += f" ({judged:.3f} without the unmatched parts)"
        elif len(missing) > self.max_missing and (
                not self.placed_missing
                or sum(x is None for x in parts.values()) > self.max_missing):
            status = "rejected"
            error = f"{len(missing)} parts unmatched ({', '.join(missing)})"
            if unordered:
                error += "; no co-optimal alignment satisfies the betweenness constraint"
        # what the hull lost and how far to trust the frame (topopose.frame.confidence)
        from topopose.frame.confidence import DROP_PARTS, Aligned, Gate, judge_frame

        status, error, extra = judge_frame(
            vol, n_vox, data, self.model, self.up, dist, self.threshold, len(missing), status,
            error, Gate(self.min_share,
                        self.min_confidence if self.gate and self.gate_rule is None else None,
                        DROP_PARTS if self.part_trust and self.gate_rule is None else (),
                        self.head_doubt), self.cap.units,
            aligned=Aligned(al, thickness_cost=thick, reach=self.thickness_reach,
                            radius_map=radii, missing_cost=mcost, parts=parts))
        if extra.get("untrusted"):     # per-part trust: unplaced, its best guess kept
            extra["untrusted_guess"] = np.round(parts[extra["untrusted"]], 6).tolist()
            parts = {**parts, extra["untrusted"]: None}
            on_skeleton[extra["untrusted"]] = None      # no curve for it either
        return status, error, extra, parts, mcost


    def _record(self, diag, vol, skel, data, al, parts, on_skeleton, hinted_parts, edt,
                sk_vox, timings):
        """Record in ``diag`` the skeleton curves of the matched arcs and what the sequence
        stage reads from them (hand hints, hull shoulders, arm evidence, trim, centre,
        support)."""
        # the skeleton curve of each matched arc, for left/right and the kinematic fit (§13.3.1)
        from topopose.frame.curves import arc_curves, model_arcs
        # hand hints: a hand unplaced by a rule (short_arm, hand_on_trunk, untrusted) whose
        # branch is matched keeps that branch's curve (its end: near the wrist, measured in
        # benchmarks/tracking.py) in diagnostics["hand_hints"] for the kinematic fit
        # (kinematic_fit.HAND_HINTS); parts, statuses and the other curves unchanged
        hinted = {p: data.positions.get(al.mapping.get(p)) for p in
                  hinted_parts
                  if al.mapping.get(p) is not None
                  and not any(u == p for u, _ in model_arcs(self.model))}     # leaves
        hinted = {p: np.asarray(x, float) for p, x in hinted.items() if x is not None}
        try:
            # (the model's [[joint]] positions along arcs are fractions of these curves)
            curves = arc_curves(skel, vol.origin, vol.voxel_size, data, al,
                                self.model, {**on_skeleton, **hinted}, voxels=sk_vox)
            hints = {p: curves.pop(p) for p in hinted if p in curves}
            diag["curves"] = curves
            if hints:
                diag["hand_hints"] = hints
            # the shoulders the trunk's cross-section below the neck tells (pose/unseen.py;
            # used by the kinematic fit, nothing else changes)
            if self.spine and diag.get("spine_shift") is not None:
                from topopose.frame.unseen import frame_hull_shoulders
                hs = frame_hull_shoulders(vol, curves, parts, self.model, diag["spine_shift"])
                if hs is not None:
                    diag["hull_shoulders"] = np.round(hs, 4).tolist()
            # an unplaced limb: the hull the matched curves leave unexplained, where it
            # can lie (pose/unseen.py; used by the kinematic fit, nothing else changes)
            if self.arm_evidence and any(parts.get(x) is None for pair, _ in
                                         self.model.mirrors for x in pair):
                from topopose.frame.unseen import hull_remainder
                diag["arm_evidence"] = np.round(hull_remainder(
                    vol, curves, edt), 4).tolist()
        except Exception as exc:           # never costs the frame its pose
            diag["curves_error"] = f"{type(exc).__name__}: {exc}"
        if self.trim and diag.get("curves") and getattr(self, "_silhouettes", None):
            from topopose.frame.trim import trimmed_curves
            t1 = time.perf_counter()
            cut = trimmed_curves(diag["curves"], parts, *self._silhouettes, vol.voxel_size)
            if cut:
                diag["trim"] = {q: c.tolist() for q, c in cut.items()}
            timings["trim"] = (time.perf_counter() - t1) * 1e3
        if self.centre and diag.get("curves") and getattr(self, "_silhouettes", None):
            # the limbs' curves onto the silhouettes' centre lines (§13.3.1)
            from topopose.frame.centre import frame_offsets
            t1 = time.perf_counter()
            cen, cen_trim = frame_offsets(diag["curves"], diag.get("trim"),
                                          *self._silhouettes, vol.data, vol.origin,
                                          vol.voxel_size, edt)
            if cen:
                diag["centred"] = cen
            if cen_trim:
                diag["centred_trim"] = cen_trim
            timings["centre"] = (time.perf_counter() - t1) * 1e3
        if self.support and diag.get("curves") and getattr(self, "_silhouettes", None):
            # analysis by synthesis: the silhouette the placed model leaves unexplained
            from topopose.frame.support import support_features
            t1 = time.perf_counter()
            sup = support_features(diag["curves"], parts, *self._silhouettes, vol.data,
                                   vol.origin, vol.voxel_size, edt, extras=False)
            diag["unexplained"] = round(sup["unexplained"], 4)
            timings["support"] = (time.perf_counter() - t1) * 1e3


    def spine_parts(self, vol, skel, data, al, parts, edt=None, voxels=None):
        """``parts`` with the body-axis parts moved back onto the spine
        (:mod:`topopose.frame.anatomy`), the shift applied (world units, or None) and the
        dropped part before its drop (``{part: position}``, {} without a drop): the legs'
        junction on the spine, the pelvis the pose descriptions compare (§13.3.2.1)."""
        from topopose.frame.anatomy import crotch_drop, front_direction, hull_radius, spine_shift

        feet = [p for p in self.model.parts if p.rstrip("_0123456789") == "foot"]
        front = front_direction(vol, skel, data, al.mapping, feet, self.up, voxels=voxels)
        if front is None:
            return parts, None, {}
        r = hull_radius(vol, edt)
        parts = spine_shift(parts, front, r, self.spine)
        before = {}
        if self.crotch_drop is not None:
            part = self.crotch_drop[0]
            if parts.get(part) is not None:
                before = {part: np.round(np.asarray(parts[part], float), 6).tolist()}
            parts = crotch_drop(parts, self.up, front, r, self.crotch_drop, vol)
        return parts, [round(float(x), 4) for x in -r * front], before

    def _failed(self, name, reason, timings, t_all):
        timings["total"] = (time.perf_counter() - t_all) * 1e3
        return Pose(name, "failed", None, {p: None for p in self.model.parts}, reason, timings,
                    {"model": self.model.name, "resolution": self.resolution,
                     "hull_tolerance": self.tolerance})


def estimate_pose(cap, frame, model="human", resolution=100, threshold=None,
                  options: EstimatorOptions | None = None, **flat) -> Pose:
    """Estimate the pose of one frame (thesis §12.1, Fig. 12.8).

    ``options`` (:class:`~topopose.frame.options.EstimatorOptions`) and ``**flat`` (options
    by :class:`FrameEstimator` parameter name, e.g. ``constraints=False``) as there.

    For many frames build one :class:`FrameEstimator` (or use :func:`topopose.run`): it
    reuses the model precomputation and the hull's projection tables.

    Examples
    --------
    >>> import topopose as tp                                        # doctest: +SKIP
    >>> cap = tp.load_capture("CAPTURE")                             # doctest: +SKIP
    >>> pose = tp.estimate_pose(cap, "000012", "human")              # doctest: +SKIP
    >>> pose.status, pose.parts["head"]                              # doctest: +SKIP
    """
    return FrameEstimator(cap, model, resolution, threshold, options, **flat).estimate(frame)
