"""Locate a clip in a venue: features -> index search -> aggregation -> the docs/formats.md answer."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from .aggregate import AGGREGATORS, SPAN_S, Estimate, confidence
from .arrays import to_numpy
from .calib.correct import ClipLens, clip_spectra
from .errors import OmninavError
from .extract import Extractor, Extractors
from .index import Index, Matches
from .lens import Lens
from .presets import FEATURE_KEYS
from .settings import SearchSettings, check
from .spectrum import LocalQuery
from .store import Store

if TYPE_CHECKING:
    from .motion import Motion
    from .tracking import Tracker
    from .tracking_state import ClipAnswer, TrackPose, TrackState
    from .verify import Outcome, PlaceIndex, Verdict
    from .walkgraph import WalkGraph

EXTRACTORS = 8  # lenses whose remaps a Locator keeps
DEFAULT_CLIP_FPS = 10.0  # timing assumed for a directory of frames, which carries none
# A clip is located by its last MAX_CLIP_S seconds, at most MAX_CLIP_FRAMES frames of them: the
# answer is the pose at the last frame, evidence from long ago says little more about it, and the
# sequence aggregation costs (frames * candidates)^2 (the tracker's fit reads twice the candidates a
# frame: Locator.clip_matches). These are the engine's, not a venue's: a venue
# modelled when a clip was cut to `max_clip_frames` (30) takes 5 s clips as well.
MAX_CLIP_S = 5.0
MAX_CLIP_FRAMES = 60
MATCH_FIELDS = tuple(f.name for f in fields(Matches))
log = logging.getLogger("omninav.locate")


def clip_groups(times: np.ndarray) -> np.ndarray:
    """(Q,) frame times of a clip -> (Q,) the second of the clip each frame is in, counted back
    from its last frame (0: the last SPAN_S): the frames that share their candidates
    (index.Index.shared). By the second, not the whole clip: a 5 s clip's first frames were filmed
    metres from its last, and the phase correlations grow with the square of the frames shared."""
    t = np.asarray(times, np.float64)
    if len(t) == 0:
        return np.zeros(0, np.int64)
    back = np.nan_to_num(t[-1] - t, nan=0.0, posinf=0.0, neginf=0.0)  # a time that is no number: the last second
    groups: np.ndarray = np.floor(np.clip(back, 0.0, MAX_CLIP_S) / SPAN_S + 1e-6).astype(np.int64)
    return groups


def answer_heading(h: float) -> float:
    """An answer's heading: degrees in [0, 360) to 0.01 (359.996 rounds to 0.0, not 360.0)."""
    return round(float(h) % 360.0, 2) % 360.0


def frame_floors(frames: np.ndarray, video_floor: Sequence[str]) -> np.ndarray:
    """(N,) str: each venue frame's floor, its modelling video's (by the video's index in the
    generation; a video beyond the list is on the first one's floor)."""
    vf = np.asarray([str(f) for f in video_floor])
    vid = np.asarray(frames["video"], np.int64)
    return vf[np.where((vid >= 0) & (vid < len(vf)), vid, 0)]


class Locator:
    """One venue's live generation loaded for answering; reuse it across queries."""

    def __init__(
        self,
        store: Store,
        venue_id: str,
        device: str | None = None,
        places: list[dict[str, Any]] | None = None,
        floor: str | None = None,
    ):
        """`places` and `floor` (from the catalogue) name the answer's place and floor; the
        server replaces both with what the matched frame's floor has (server/locate_api.py)."""
        self.venue_id = venue_id
        self.places = places or []
        self.floor = floor
        self.generation = store.generation(venue_id)  # read first: a newer load is only ever refreshed again
        self.gen = store.load(venue_id)
        self.conf = self.gen.settings  # (a superseded confidence model is read as today's: store._read_settings)
        self.search = SearchSettings.of(self.conf)  # the index's search parameters, read once
        self.xy = np.stack([self.gen.frames["x"], self.gen.frames["y"]], -1).astype(np.float64)
        self.index = Index(
            self.gen.spectra,
            self.gen.frames["heading"],
            device=device,
            key_dims=self.search.key_dims_for(len(self.gen.frames)),
            arrays=self.gen.arrays,
        )
        self._extractors = Extractors(self.conf, EXTRACTORS)
        self._graph: WalkGraph | None = None
        self._tracker: Tracker | None = None
        self._frame_floor: np.ndarray | None = None  # (V,) each venue frame's floor, with use_floors
        self._frame_lock = threading.Lock()
        self._frame_k = 0
        self._frame_m: dict[int, tuple[np.ndarray, ...]] = {}  # frame_matches, by venue frame row
        self._places: tuple[np.ndarray, PlaceIndex] | None = None  # verify.place_of_rows, place_index

    def extractor(self, lens: Lens | None) -> Extractor:
        """The extractor of a lens (default: the venue's), from a small shared cache."""
        return self._extractors.get(lens or self.gen.lens)

    def clip_lens(self, lens: Lens | None, check: Callable[[np.ndarray], None] | None = None) -> ClipLens[np.ndarray]:
        """A clip's frames -> spectra through `lens` (default: the venue's) corrected for where the
        ring sits in this clip (calib/correct.py)."""
        return ClipLens(lens or self.gen.lens, self._extractors.spectrum, check)

    def estimate(self, q_spec: np.ndarray, times: np.ndarray | None = None, aggregate: str | None = None) -> Estimate:
        agg = self._aggregation(aggregate)
        m, times = self.search_clip(q_spec, times)
        return self.aggregated(m, times, agg)

    def aggregated(self, m: Matches, times: np.ndarray, aggregate: str | None = None) -> Estimate:
        """A clip's matches and times (search_clip's) -> its answer, aggregated as estimate() does."""
        return AGGREGATORS[self._aggregation(aggregate)](m, self.xy, times, self.conf)

    def _aggregation(self, aggregate: str | None) -> str:
        agg = aggregate or self.conf["aggregate"]
        if agg not in AGGREGATORS:
            raise OmninavError(f"unknown aggregation {agg!r} (use median or sequence)")
        return str(agg)

    def change_settings(self, changes: Mapping[str, Any]) -> None:
        """Search, aggregation or confidence settings changed for this Locator's answers (a bench's
        `--set`, a test): checked, and the search parameters read again. Feature settings cannot
        change (the venue's frames were made with them, and so are the Locator's extractors), nor
        the keys' projection (the index)."""
        fixed = sorted(set(changes) & {*FEATURE_KEYS, "key_dims", "key_project_above", "local_features"})
        if fixed:
            raise OmninavError(f"{', '.join(fixed)}: fixed when the venue was modelled")
        conf = {**self.conf, **changes}
        check(conf)
        self.conf = conf
        self.search = SearchSettings.of(conf)
        self._tracker = None  # (it keeps its own copy of the settings: the next one reads these)

    def search_clip(self, q_spec: np.ndarray, times: np.ndarray | None) -> tuple[Matches, np.ndarray]:
        """A clip's candidate matches (its last MAX_CLIP_S, at most MAX_CLIP_FRAMES) and their times,
        searched as every answer is: the frames of each second of the clip share their candidates
        (clip_groups, index.Index.shared) unless the venue's `shared_candidates` is off."""
        m, _, times = self.clip_matches(q_spec, times)
        return m, times

    def clip_matches(self, q_spec: np.ndarray, times: np.ndarray | None) -> tuple[Matches, Matches, np.ndarray]:
        """search_clip(), and the tracker's evidence: each frame's shared best and, beside them,
        its own stage-1 candidates as verified (2 x `candidates` a frame; with `shared_candidates`
        off, the frame's own candidates, the same as the answer's). Why both for the tracker: its
        emission counts a node that none of a frame's matches is near as the frame's worst kept
        score. Of the shared best alone, that floor sits as high as every door of a corridor of
        identical doors, and a track along one slid a door for seconds at a time (long-bare and
        ring-bare, with the phone's steps); the frame's own candidates keep the floor where it
        was, and the shared best still give the places the clip found their verified scores
        (docs/benchlog.md, "Shared candidates")."""
        if q_spec.ndim != 3 or q_spec.shape[0] == 0:
            raise OmninavError("a clip needs at least one frame")
        if times is None:
            times = np.arange(q_spec.shape[0]) / DEFAULT_CLIP_FPS
        times = np.asarray(times, np.float64)
        if len(times) != len(q_spec):
            raise OmninavError(f"a clip of {len(q_spec)} frames needs {len(q_spec)} frame times, got {len(times)}")
        # the frames less than MAX_CLIP_S before the last (50 at 10 frames/s), at most MAX_CLIP_FRAMES
        keep = max(1, min(MAX_CLIP_FRAMES, int(np.count_nonzero(times > times[-1] - MAX_CLIP_S + 1e-6))))
        q_spec, times = q_spec[-keep:], times[-keep:]
        k = self.search.candidates
        if not self.search.shared_candidates:
            m = self.index.search(q_spec, k)
            return m, m, times
        shortlist = self.search.shortlist
        best, own = self.index.search_shared(q_spec, k, clip_groups(times), shortlist)
        both = Matches(*(np.concatenate([getattr(best, f), getattr(own, f)], axis=1) for f in MATCH_FIELDS))
        return best, both, times

    # ---- tracking while walking (tracking.py) ----------------------------------------------------
    @property
    def graph(self) -> WalkGraph:
        """The walk graph of this generation's modelling walks: as `use_floors` set it (every
        video on its own floor, lifts and stairs joining them), else all on the Locator's one
        floor (the server builds its own with every video's floor and the venue's places)."""
        if self._graph is None:
            from .walkgraph import from_frames

            floor = str(self.floor or "1")
            self._graph = from_frames(self.gen.frames, [floor] * max(1, len(self.gen.videos)), self.places)
        return self._graph

    def use_floors(self, video_floor: Sequence[str], graph: WalkGraph) -> None:
        """Track on `graph` (walkgraph.from_frames with each modelling video's floor, by its index
        in the generation, and the venue's places), each venue frame on its video's floor: walks
        of two floors at the same x, y stay apart, and the answers name the pose's floor."""
        if len(video_floor) == 0:
            raise ValueError("use_floors needs each modelling video's floor")
        self._frame_floor = frame_floors(self.gen.frames, video_floor)
        self._graph = graph
        self._tracker = None

    @property
    def tracker(self) -> Tracker:
        """The tracking filter over `graph` (built once: its precomputed neighbourhoods)."""
        if self._tracker is None:
            floor = np.full(len(self.xy), str(self.floor or "1")) if self._frame_floor is None else self._frame_floor
            self._tracker = self.new_tracker(self.graph, floor)
        return self._tracker

    def new_tracker(self, graph: WalkGraph, floor: np.ndarray, conf: dict[str, Any] | None = None) -> Tracker:
        """A tracking filter over `graph` (each venue frame's floor: `floor`) with this venue's
        look-alikes (frame_matches, kept here); `conf` over the venue's settings. For a caller
        with its own graph (the server's runtime of a catalogue revision), the Locator unchanged."""
        from .lookalikes import look_alikes
        from .tracking import Tracker

        conf = {**self.conf, **(conf or {})}
        return Tracker(graph, self.xy, floor, conf, look_alikes(self.frame_matches, graph, self.xy, floor, conf))

    def frame_matches(self, rows: np.ndarray, k: int) -> Matches:
        """Venue frames' own matches in this venue's index (lookalikes.look_alikes: each walk graph
        node's frame), kept per frame: a server's runtime is rebuilt on every catalogue change
        (places, floors) with the same Locator, and its new walk graph's nodes mostly sit on the
        same frames, so only frames not searched before are. Thread-safe (runtimes share it)."""
        from .lookalikes import frame_search

        rows = np.asarray(rows, np.int64)
        with self._frame_lock:
            if self._frame_k != k:
                self._frame_k, self._frame_m = k, {}
            todo = np.unique([r for r in rows.tolist() if r not in self._frame_m]).astype(np.int64)
            if len(todo):
                got = frame_search(self.index.search, self.gen.spectra)(todo, k)
                for i, r in enumerate(todo.tolist()):
                    self._frame_m[r] = tuple(np.asarray(getattr(got, f))[i] for f in MATCH_FIELDS)
            kept = [self._frame_m[r] for r in rows.tolist()]
        if not kept:
            return Matches(*(np.zeros((0, k)) for _ in MATCH_FIELDS))
        return Matches(*(np.stack([m[i] for m in kept]) for i in range(len(MATCH_FIELDS))))

    def track(
        self,
        tracker: Tracker,
        q_spec: np.ndarray,
        times: np.ndarray | None,
        state: TrackState | None,
        t_now: float | None = None,
        motion: Motion | None = None,
        aggregate: str | None = None,
    ) -> tuple[TrackState, TrackPose, Estimate]:
        """One clip -> the filter's new state and pose, and the clip's own Estimate: one index
        search feeds both. `times`: the clip's frame times; `t_now` (default: the last of them)
        the caller's clock at the clip's last frame (the frame times are shifted onto it).

        A clip longer than a second (what the phone filmed since its last request) is walked
        second by second (Tracker.update_clip), `motion` shared among the seconds; the Estimate
        returned is the whole clip's, as a locate without a session answers it."""
        agg = self._aggregation(aggregate)
        m, evidence, times = self.clip_matches(q_spec, times)
        e = AGGREGATORS[agg](m, self.xy, times, self.conf)
        now = float(times[-1]) if t_now is None else float(t_now)
        new, pose = tracker.update_clip(
            state, evidence, times - times[-1] + now, now, motion, self.own_answers(e, len(times), agg)
        )
        return new, pose, e

    def own_answers(
        self, whole: Estimate, frames: int, aggregate: str | None = None
    ) -> Callable[[Matches, np.ndarray], ClipAnswer]:
        """What each part of a clip answers alone (the venue's aggregation; its confidence by the
        rules' own model of the clip and by the venue's, `alone`: ClipAnswer.of), for the filter's
        rules of the clip's own answer (Tracker.update_clip): `whole`, the clip's own Estimate,
        when the part is the whole clip (`frames` frames), else the part's, from the part's first
        `candidates` matches a frame (of the tracker's evidence, clip_matches: the shared best, as
        a locate answers)."""
        from .tracking_state import ClipAnswer

        agg = self._aggregation(aggregate)
        k = self.search.candidates

        def own(m: Matches, times: np.ndarray) -> ClipAnswer:
            if len(times) == frames:
                return ClipAnswer.of(whole, self.conf)
            m = Matches(*(np.asarray(getattr(m, f))[:, :k] for f in MATCH_FIELDS))
            return ClipAnswer.of(AGGREGATORS[agg](m, self.xy, times, self.conf), self.conf)

        return own

    def track_answer(self, pose: TrackPose, clip: str, t: float | None = None) -> dict[str, Any]:
        """A filtered pose -> the answer (docs/formats.md's fields, `t`, and `ambiguous`)."""
        on = self._frame_floor is None or self._frame_floor == pose.floor  # the pose's floor's frames
        row = int(np.argmin(np.where(on, np.hypot(self.xy[:, 0] - pose.x, self.xy[:, 1] - pose.y), np.inf)))
        floor = self.floor if self._frame_floor is None else pose.floor
        out: dict[str, Any] = {"clip": clip}
        if t is not None:
            out["t"] = round(t, 3)
        out.update(
            {
                "x": round(pose.x, 3),
                "y": round(pose.y, 3),
                "heading_deg": answer_heading(pose.heading),
                "confidence": round(pose.confidence, 3),
                "floor": floor,
                "place": self.nearest_place(pose.x, pose.y, None if self._frame_floor is None else floor),
                "frame": int(self.gen.frames["frame"][row]),
                "ambiguous": pose.ambiguous,
            }
        )
        return out

    def confidence(self, e: Estimate, outcome: Outcome | None = None) -> float:
        """An estimate's confidence: the venue's model's, as verification's `outcome` leaves it
        (verify.checked_confidence; None: not verified). The answer's, evaluate's and the benches'."""
        from .verify import checked_confidence

        return checked_confidence(outcome, confidence(e, self.conf))

    def answer(self, e: Estimate, clip: str, outcome: Outcome | None = None) -> dict[str, Any]:
        """The docs/formats.md answer of an estimate; `outcome`: what verification made of it
        (verify.Verdict.outcome; None: not verified), which sets its confidence with the model's."""
        return {
            "clip": clip,
            "x": round(e.x, 3),
            "y": round(e.y, 3),
            "heading_deg": answer_heading(e.heading),
            "confidence": round(self.confidence(e, outcome), 3),
            "floor": self.floor,
            "place": self.nearest_place(e.x, e.y),
            "frame": int(self.gen.frames["frame"][e.venue_row]),
            **({"verified": outcome} if outcome is not None else {}),
        }

    def nearest_place(self, x: float, y: float, floor: str | None = None) -> str | None:
        """The name of the place nearest (x, y) (on `floor`, when given and the places say theirs)."""
        places = self.places
        if floor is not None:
            places = [p for p in places if str(p.get("floor", floor)) == floor]
        if not places:
            return None
        d = [np.hypot(p["x"] - x, p["y"] - y) for p in places]
        return str(places[int(np.argmin(d))]["name"])

    def locate_spectra(
        self,
        spec: np.ndarray,
        clip: str,
        fps: float | None = None,
        aggregate: str | None = None,
        local: LocalQuery | None = None,
    ) -> dict[str, Any]:
        """A clip's decoded feature record -> the answer (what the phone's request becomes);
        verified where the record brings its last frame's local features and the venue has some."""
        times = np.arange(len(spec)) / (fps or DEFAULT_CLIP_FPS)
        e, outcome = self.estimate_local(spec, times, aggregate, local)
        return self.answer(e, clip, outcome)

    def locate_frames(
        self,
        frames: list[np.ndarray],
        clip: str,
        lens: Lens | None = None,
        fps: float | None = None,
        aggregate: str | None = None,
    ) -> dict[str, Any]:
        """A clip's frames -> the answer; verified by local features where the venue has them."""
        ext = self.extractor(lens)
        for f in frames[:1]:
            ext.check_frame(f, clip)
        spec, c = clip_spectra(lens or self.gen.lens, frames, self._extractors.spectrum, clip=clip)
        times = np.arange(len(frames)) / (fps or DEFAULT_CLIP_FPS)
        local = self.local_features(frames[-1], c.lens) if self.verifies else None
        e, outcome = self.estimate_local(spec, times, aggregate, local)
        return self.answer(e, clip, outcome)

    @property
    def verifies(self) -> bool:
        """Whether the venue has local features to verify a clip with (verify.py)."""
        return self.gen.local is not None and bool(self.conf.get("local_features"))

    def local_features(self, frame: np.ndarray, lens: Lens) -> LocalQuery | None:
        """A clip's last frame -> its local features (verify.detect), seen through `lens` (the
        clip's, corrected for where its ring sits), as many as the venue keeps a place; None where
        OpenCV fails on it (logged: the clip is answered by its curves)."""
        from .verify import detect

        try:
            return detect(frame, lens, int(self.conf["local_features"]))
        except (cv2.error, ValueError) as err:
            log.warning("local features not found, the clip is not verified: %s", err)
            return None

    def estimate_local(
        self, q_spec: np.ndarray, times: np.ndarray, aggregate: str | None, local: LocalQuery | None
    ) -> tuple[Estimate, Outcome | None]:
        """estimate(), then verified by the clip's last frame's `local` features where there are
        some and the venue has its own: (the estimate, what verification made of it: None where
        the clip was not verified; verify.Verdict.outcome)."""
        m, times = self.search_clip(q_spec, times)
        e = self.aggregated(m, times, aggregate)
        if local is None or not self.verifies:
            return e, None
        return self.verified(local, m, e, q_spec)

    def verified(
        self, local: LocalQuery, m: Matches, e: Estimate, last_specs: np.ndarray
    ) -> tuple[Estimate, Outcome | None]:
        """A clip's global answer checked by its last frame's local features against its candidate
        places: (the answer, "moved") moved to another place with the heading of the last frame's
        spectrum (of the clip's `last_specs`, (F, C, K)) at that place (stage 2's phase
        correlation), (the answer where it was, "confirmed"), the heading of either checked by the
        keypoints (_keypoints_heading); or (as it was, "unconfirmed"; None where nothing could be
        compared). Verification only ever adds to the answer: an error in it is logged and the
        global answer stands, not verified (None)."""
        from . import verify as vfy

        stored = self.gen.local
        assert stored is not None
        try:
            place_of, index = self.verification_places()
            wide = (lambda: self.index.search(last_specs[-vfy.WIDE_FRAMES :], vfy.WIDE_K)) if vfy.WIDE_K else None
            margin = float(self.conf["local_margin"])
            v = vfy.verify(local, m, self.xy, stored, place_of, e.venue_row, margin, wide, index)
            if v.outcome not in ("moved", "confirmed"):
                return e, v.outcome
            if v.moved_to is None:  # confirmed: where it was, its heading checked
                h = self._keypoints_heading(v, int(place_of[e.venue_row]), e.heading, index)
                return replace(e, heading=h), v.outcome
            r = v.moved_to
            _, heading = self.index.verify(np.asarray(last_specs[-1])[None], np.array([[r]]))  # the curves' there
            h = self._keypoints_heading(v, int(place_of[r]), float(to_numpy(heading).ravel()[0]), index)
        except (cv2.error, np.linalg.LinAlgError, ValueError, RuntimeError) as err:  # (RuntimeError: numba's cache)
            log.warning("verification failed, the global answer stands: %s", err)
            return e, None
        x, y = self.xy[r]
        return Estimate(float(x), float(y), h, r, e.support, e.rival, e.agree), v.outcome

    def verification_places(self) -> tuple[np.ndarray, PlaceIndex]:
        """The venue's stored places as verification finds them (verify.place_of_rows and
        place_index), made at its first verification or warm-up; and verification's compiled
        loops loaded (essential.py, hamming.py: ~0.5 s a process from numba's cache, seconds the
        first time)."""
        if self._places is None:
            from . import verify as vfy
            from .essential import sample_counts
            from .hamming import two_nearest

            stored = self.gen.local
            assert stored is not None
            rows = self.gen.frames
            self._places = vfy.place_of_rows(rows, stored), vfy.place_index(rows, stored, self.xy)
            sample_counts(np.zeros((8, 9)), np.zeros((8, 3)), np.zeros((8, 3)), np.zeros((1, 8), np.int64), 1.0)
            two_nearest(np.zeros((1, vfy.DESCRIPTOR_BYTES), np.uint8), np.zeros((2, vfy.DESCRIPTOR_BYTES), np.uint8))
        return self._places

    def _keypoints_heading(self, v: Verdict, place: int, curves: float, index: PlaceIndex) -> float:
        """A verified answer's heading: the curves' (`curves`), unless the keypoints' turn from
        `place`'s modelled frame (verify.turn_deg of the verdict's essential matrix, fitted to
        that place) puts it more than HEADING_AGREE_DEG away. An error in it leaves the curves'
        (logged): the answer stays verified."""
        from . import verify as vfy

        if v.essential is None or place < 0 or index.rows[place] < 0:
            return curves
        try:
            turn = vfy.turn_deg(v.essential)
        except (np.linalg.LinAlgError, ValueError) as err:
            log.warning("the keypoints' heading failed, the curves' stands: %s", err)
            return curves
        keyed = float(self.gen.frames["heading"][index.rows[place]]) + turn
        off = (keyed - curves + 180.0) % 360.0 - 180.0
        return curves if abs(off) <= vfy.HEADING_AGREE_DEG else keyed % 360.0


def read_record(path: Path, conf: dict[str, Any]) -> tuple[np.ndarray, LocalQuery | None]:
    """A feature record file (.onv binary or .json) -> ((F, C, K) spectra, its local features or
    None), checked against conf."""
    import json

    from .spectrum import decode_binary_local, decode_json_local

    if not path.is_file():
        raise OmninavError(f"{path}: feature record not found")
    try:
        if path.suffix.lower() == ".onv":
            return decode_binary_local(path.read_bytes(), conf)
        try:
            obj = json.loads(path.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise OmninavError(f"feature record is not readable JSON ({e})") from None
        return decode_json_local(obj, conf)
    except OmninavError as e:  # say which of several files on the command line was wrong
        raise OmninavError(f"{path}: {e}") from None


RECORD_SUFFIXES = (".onv", ".json")


def clip_frames(path: Path, sample_fps: float) -> tuple[list[np.ndarray], float]:
    """A query clip's frames, resampled to about `sample_fps` if it is a faster video."""
    from .video import read_clip

    frames, fps = read_clip(path)
    if fps is None:
        return frames, DEFAULT_CLIP_FPS
    stride = max(1, int(round(fps / sample_fps)))
    # keep the last frame: the answer is the pose there
    keep = frames[::-1][::stride][::-1]
    return keep, fps / stride
