"""The public Python API of ggs (re-exported by ``ggs``); the native engine is ``ggs._ggs``."""

from __future__ import annotations

import copy
import json
import os
import warnings
from typing import (
    Any,
    Callable,
    Dict,
    Iterable,
    List,
    Literal,
    NamedTuple,
    Optional,
    Sequence,
    Tuple,
    Union,
)

import numpy as np
import numpy.typing as npt

from . import _ggs

Preset = Literal["default", "paper"]
RotationSetName = Literal[
    "hopf15-id", "limited15", "full15", "limited10", "hopf15", "hopf15-dedup", "ico162-s10"
]
Method = Literal["gicp", "p2plane", "p2p"]
RefineMethod = Literal["gicp", "p2plane", "p2p", "none"]
SearchMode = Literal["exhaustive", "coarse-to-fine"]
Precision = Literal["mixed", "f64"]
#: (N, 3) float32/float64 arrays, anything ``numpy.asarray`` turns into one (lists, tuples,
#: torch tensors on the CPU), or an object with a ``.points`` attribute (Open3D PointCloud).
PointsLike = Any
Matrix4 = npt.NDArray[np.float64]
Points = npt.NDArray[np.float64]
StrPath = Union[str, "os.PathLike[str]"]
ProgressCallback = Callable[[int, int], None]


class GgsWarning(UserWarning):
    """A result that is probably wrong or not unique: ambiguous poses, low evidence,
    degenerate geometry. Filter with ``warnings.simplefilter("ignore", ggs.GgsWarning)``."""


def as_points(obj: PointsLike, name: str = "points") -> npt.NDArray[Any]:
    """``obj`` as an (N, 3) float array: float32/float64 arrays pass as they are, an object
    with ``.points`` (Open3D) gives its points, anything else goes through ``numpy.asarray``.
    The shape is checked by the engine (a ValueError naming ``name``)."""
    pts = getattr(obj, "points", obj)
    if isinstance(pts, np.ndarray) and pts.dtype in (np.float32, np.float64):
        return pts
    try:
        return np.asarray(pts, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot read it as an (N, 3) array of floats ({e})") from None


def _threads(threads: Optional[int]) -> int:
    if threads is None:
        return 0
    if not isinstance(threads, int) or threads < 0:
        raise ValueError(f"threads must be None (all cores) or an integer ≥ 0, got {threads!r}")
    return threads


class Result:
    """The outcome of :func:`register` or :func:`refine`; picklable, and ``to_dict()`` gives
    every field as plain Python and numpy values."""

    def __init__(self, document: Dict[str, Any], report: Any = None) -> None:
        self._document = document
        self._fields = _fields_of(document)
        self._report = report

    def __getstate__(self) -> Dict[str, Any]:
        # The report's display samples stay behind: an unpickled Result has no report.
        return {"_document": self._document}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self._document = state["_document"]
        self._fields = _fields_of(self._document)
        self._report = None

    @property
    def document(self) -> Dict[str, Any]:
        """The result as ``ggs register --json`` prints it (``format``
        ``"ggs-registration/2"``; ``"ggs-refinement/1"`` for :func:`refine`): every field
        of the run, nested as docs/cli.md, "The JSON result" describes. A deep copy."""
        return copy.deepcopy(self._document)

    def report_html(
        self,
        path: StrPath,
        *,
        source_name: str = "source",
        target_name: str = "target",
        command: Optional[str] = None,
    ) -> None:
        """Write the registration report, one self-contained HTML file: the target and the
        source before and after in three views, a 3-D view, the hypotheses and their
        verification, the quality report with its definitions, the time of each stage, and
        ``command`` (shown as the line that reproduces it). The same page as
        ``ggs register --report``. Written atomically.

        Only a Result of :func:`register` in this process has one (it keeps at most 200 000
        points of each cloud for the pictures); ValueError otherwise.
        """
        if self._report is None:
            raise ValueError(
                "this Result has no report: only ggs.register results have one, and it is "
                "not pickled"
            )
        self._report.write(os.fspath(path), source_name, target_name, command)

    @property
    def transformation(self) -> Matrix4:
        """The final 4×4 float64 transform, ``p_target = T · p_source``."""
        return self._fields["transformation"]  # type: ignore[no-any-return]

    @property
    def coarse_transformation(self) -> Optional[Matrix4]:
        """The chosen hypothesis's grid transform, before ICP (None after :func:`refine`)."""
        return self._fields["coarse_transformation"]  # type: ignore[no-any-return]

    @property
    def fitness(self) -> Optional[float]:
        """Share of source points within the correspondence distance after refinement (None
        with ``refine="none"``)."""
        return self._fields["fitness"]  # type: ignore[no-any-return]

    @property
    def fitness_target(self) -> Optional[float]:
        """Share of target points matched after refinement."""
        return self._fields["fitness_target"]  # type: ignore[no-any-return]

    @property
    def inlier_rmse(self) -> Optional[float]:
        """RMS distance of the inlier correspondences after refinement, in the clouds' units."""
        return self._fields["inlier_rmse"]  # type: ignore[no-any-return]

    @property
    def converged(self) -> Optional[bool]:
        """Whether the refinement converged."""
        return self._fields["converged"]  # type: ignore[no-any-return]

    @property
    def score(self) -> Optional[int]:
        """The coarse winner's exact integer score (None after :func:`refine`)."""
        return self._fields["score"]  # type: ignore[no-any-return]

    @property
    def ambiguity(self) -> Optional[float]:
        """Coarse ambiguity: the best distinct rotation's match score over the winner's."""
        return self._fields["ambiguity"]  # type: ignore[no-any-return]

    @property
    def rotation_index(self) -> Optional[int]:
        """Index of the coarse winner in the rotation set."""
        return self._fields["rotation_index"]  # type: ignore[no-any-return]

    @property
    def voxel(self) -> Optional[float]:
        """The voxel size of the grid search."""
        return self._fields["voxel"]  # type: ignore[no-any-return]

    @property
    def confidence(self) -> Optional[float]:
        """In [0, 1]: 1 − (verification score of the best distinct runner-up) / (the chosen
        pose's); without a verified runner-up, 1 − the coarse ambiguity."""
        return self._fields["confidence"]  # type: ignore[no-any-return]

    @property
    def ambiguous(self) -> Optional[bool]:
        """True when two distinct poses explain the data about equally well."""
        return self._fields["ambiguous"]  # type: ignore[no-any-return]

    @property
    def warnings(self) -> List[str]:
        """What the user should know (also issued as :class:`GgsWarning`)."""
        return self._fields["warnings"]  # type: ignore[no-any-return]

    @property
    def chosen_rank(self) -> Optional[int]:
        """Coarse rank of the chosen hypothesis (0: the coarse winner)."""
        return self._fields["chosen_rank"]  # type: ignore[no-any-return]

    @property
    def hypotheses(self) -> List[Dict[str, Any]]:
        """The best distinct coarse hypotheses, best first (rotation_index, score,
        match_score, offset, transformation)."""
        return self._fields["hypotheses"]  # type: ignore[no-any-return]

    @property
    def verified(self) -> List[Dict[str, Any]]:
        """The verified hypotheses in coarse rank order (rank, rotation_index, match_score,
        polished_match_score, score, fitness_source, fitness_target, iterations,
        rejected_early, rejected_on_subsample: rejected on a random part of the points,
        evidence_points: the source and target points the score summed,
        free_space_violations: the share of points in the space the other cloud, a scan
        from its origin, saw through (None when neither cloud is one), level, settled,
        same_as: the rank of the earlier hypothesis whose
        pose it reached and whose score it carries, or None; screened: verified by the
        first look's screening, on cells of one voxel; chosen, runner_up,
        coarse_transformation, transformation)."""
        return self._fields["verified"]  # type: ignore[no-any-return]

    @property
    def first_look(self) -> Optional[Dict[str, Any]]:
        """What the first look did (None where it did not run: ``preset="paper"``,
        ``first_look=False``, no verification, :func:`refine`): ``rotations`` scored at the
        voxel size, hypotheses ``verified``, the chosen pose's ``score``, the best distinct
        ``runner_up_score`` (or None), the least score it takes (``accept_score``), and
        whether it was ``accepted`` (the whole search was then not run)."""
        return self._fields["first_look"]  # type: ignore[no-any-return]

    @property
    def report(self) -> Optional[Dict[str, Any]]:
        """The refinement's quality report (fitness both ways, RMSE, eigenvalues, ...)."""
        return self._fields["report"]  # type: ignore[no-any-return]

    @property
    def timings(self) -> Dict[str, float]:
        """Milliseconds, the same keys in every mode (0.0 for a stage that did not run):
        coarse_ms, target_ms, extents_ms, search_ms, verify_ms, refine_ms, total_ms."""
        return self._fields["timings"]  # type: ignore[no-any-return]

    @property
    def settings(self) -> Optional[Dict[str, Any]]:
        """Every setting in force (None for :func:`refine`): pass it as ``settings=`` to
        register another pair the same way."""
        return self._fields["settings"]  # type: ignore[no-any-return]

    def to_dict(self) -> Dict[str, Any]:
        """Every field, deep-copied."""
        return copy.deepcopy(self._fields)

    def __repr__(self) -> str:
        f = self._fields
        parts = []
        for key in ("rotation_index", "score", "confidence", "ambiguous", "fitness", "inlier_rmse"):
            v = f.get(key)
            if v is not None:
                parts.append(f"{key}={v:.4g}" if isinstance(v, float) else f"{key}={v}")
        rows = np.array2string(f["transformation"], precision=6, suppress_small=True)
        return f"ggs.Result({', '.join(parts)},\n  transformation=\n{rows})"


def _matrix(rows: Any) -> Matrix4:
    return np.array(rows, dtype=np.float64)


def _verified_of(verification: Optional[Dict[str, Any]]) -> List[Dict[str, Any]]:
    """The verified hypotheses of a document, one flat dict each."""
    if verification is None:
        return []
    out = []
    for k, h in enumerate(verification["hypotheses"]):
        e = h["evidence"]
        out.append({
            "rank": h["rank"], "rotation_index": h["rotation_index"],
            "match_score": h["match_score"], "polished_match_score": h["polished_match_score"],
            "score": e["score"], "fitness_source": e["fitness_source"],
            "fitness_target": e["fitness_target"], "iterations": h["iterations"],
            "rejected_early": h["rejected_early"], "rejected_on_subsample": h["rejected_on_subsample"],
            "evidence_points": e["points"],
            "free_space_violations": e.get("free_space_violations"),
            "level": h["level"], "settled": h["settled"], "same_as": h["same_as"],
            "screened": h["screened"], "chosen": k == verification["chosen"],
            "runner_up": k == verification["runner_up"],
            "coarse_transformation": _matrix(h["coarse_transform"]),
            "transformation": _matrix(h["transform"]),
        })  # fmt: skip
    return out


def _fields_of(doc: Dict[str, Any]) -> Dict[str, Any]:
    """The flat fields of :class:`Result`, read from a result's document: every key present
    in every mode, None (or 0.0 for a time) where a stage did not run."""
    refined: Optional[Dict[str, Any]] = doc.get("refine")
    q = refined["report"] if refined else None
    search = doc.get("search")
    winner = search["hypotheses"][0] if search else None
    t = (search or {}).get("timings", {})
    report = {"method": refined["method"], **refined["report"]} if refined else None
    return {
        "transformation": _matrix(doc["transform"]),
        "fitness": q and q["fitness_source"],
        "fitness_target": q and q["fitness_target"],
        "inlier_rmse": q and q["inlier_rmse"],
        "converged": q and q["converged"],
        "report": report,
        "coarse_transformation": _matrix(doc["coarse_transform"]) if search else None,
        "score": winner and winner["score"],
        "ambiguity": search and search["ambiguity"],
        "rotation_index": winner and winner["rotation_index"],
        "voxel": doc.get("voxel"),
        "confidence": doc.get("confidence"),
        "ambiguous": doc.get("ambiguous"),
        "chosen_rank": doc.get("chosen_rank"),
        "warnings": list(doc.get("warnings", [])),
        "hypotheses": [
            {**{k: h[k] for k in ("rotation_index", "score", "match_score", "offset")},
             "transformation": _matrix(h["transform"])}
            for h in (search["hypotheses"] if search else [])
        ],  # fmt: skip
        "verified": _verified_of(doc.get("verification")),
        "first_look": doc.get("first_look"),
        "timings": {
            "coarse_ms": t.get("total_ms", 0.0),
            "target_ms": t.get("target_ms", 0.0),
            "extents_ms": t.get("extents_ms", 0.0),
            "search_ms": t.get("search_ms", 0.0),
            "verify_ms": doc["timings"]["verify_ms"] if search else 0.0,
            "refine_ms": refined["total_ms"] if refined else 0.0,
            "total_ms": doc["total_ms"],
        },
        "settings": doc.get("settings"),
    }


def _warn(result: Result) -> Result:
    for w in result.warnings:
        warnings.warn(w, GgsWarning, stacklevel=3)
    report = result.report
    if report is not None and report["degenerate"]:
        warnings.warn(
            "degenerate geometry: some motion is barely constrained by the data "
            "(see report['information_eigenvalues'])",
            GgsWarning,
            stacklevel=3,
        )
    return result


def _plain(value: Any) -> Any:
    """A numpy scalar as its Python number, for JSON."""
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"cannot pass {value!r} as a setting")


def native_options(
    preset: Optional[Preset] = None,
    settings: Union[Dict[str, Any], StrPath, None] = None,
    rotations: Union[RotationSetName, StrPath, npt.NDArray[np.float64], None] = None,
    threads: Optional[int] = None,
    **keywords: Any,
) -> Tuple[Dict[str, Any], Optional[npt.NDArray[np.float64]]]:
    """The options of :func:`register` as the native engine takes them (plain values: the
    preset, the settings file, the layers of changes as JSON, the threads), and the rotation
    matrices when ``rotations`` is an array. The engine reads and checks every setting."""
    matrices = None
    if isinstance(rotations, (str, os.PathLike)):
        keywords["rotations"] = os.fspath(rotations)
    elif rotations is not None:
        matrices = np.ascontiguousarray(rotations, dtype=np.float64)
    file = None
    layers = []
    if isinstance(settings, (str, os.PathLike)):
        file = os.path.abspath(os.fspath(settings))
    elif settings is not None:
        layers.append(["settings", json.dumps(dict(settings), default=_plain)])
    given = {k: v for k, v in keywords.items() if v is not None}
    if given:
        layers.append(["keyword arguments", json.dumps(given, default=_plain)])
    native = {"preset": preset, "file": file, "layers": layers, "threads": _threads(threads)}
    return native, matrices


def settings(
    preset: Optional[Preset] = None,
    settings: Union[Dict[str, Any], StrPath, None] = None,
    **keywords: Any,
) -> Dict[str, Any]:
    """Every setting a :func:`register` call with these arguments would use, as a dict: the
    preset (``None``: the settings file's, else ``"default"``) changed by ``settings`` (a
    dict, or a TOML/JSON settings file as ``ggs settings`` writes it), then by the keyword
    arguments (any settings key). Raises ValueError for an unknown key or a bad value."""
    native, _ = native_options(preset, settings, **keywords)
    result: Dict[str, Any] = json.loads(_ggs.settings(native))
    return result


def register(
    source: PointsLike,
    target: PointsLike,
    voxel: Optional[float] = None,
    *,
    preset: Optional[Preset] = None,
    settings: Union[Dict[str, Any], StrPath, None] = None,
    rotations: Union[RotationSetName, StrPath, npt.NDArray[np.float64], None] = None,
    refine: Optional[RefineMethod] = None,
    kernel: Optional[str] = None,
    threads: Optional[int] = None,
    top_k: Optional[int] = None,
    search: Optional[SearchMode] = None,
    precision: Optional[Precision] = None,
    max_hypotheses: Optional[int] = None,
    margin: Optional[float] = None,
    verify_score: Optional[str] = None,
    verify: Optional[bool] = None,
    first_look: Optional[bool] = None,
    polish: Optional[bool] = None,
    max_memory: Union[int, str, None] = None,
    distinct_radius: Optional[float] = None,
    dedup: Optional[float] = None,
    coarse_factor: Optional[float] = None,
    coarse_keep: Optional[float] = None,
    coarse_keep_min: Optional[int] = None,
    coarse_hypotheses: Optional[int] = None,
    max_distance: Optional[float] = None,
    distance_quantile: Optional[float] = None,
    max_iterations: Optional[int] = None,
    neighbors: Optional[int] = None,
    refine_cell: Optional[float] = None,
    progress: Optional[ProgressCallback] = None,
) -> Result:
    """Register ``source`` onto ``target`` with no initial guess.

    source, target: (N, 3) points: arrays, array-likes, or objects with ``.points`` (Open3D).
    voxel: grid size in the clouds' units (default: the target's longest side / 32, or
      1.5 × the clouds' point spacing when that is larger).
    preset: ``"default"`` — the full-SO(3) rotation set ``hopf15-id``, the coarse-to-fine
      search, then the distinct coarse hypotheses refined on thinned clouds and scored by how
      closely both clouds lie to each other within a fixed distance, the best refined by
      GICP — or ``"paper"``, the GGS paper's configuration (``limited15``, exhaustive, one
      hypothesis, GICP). ``None``: the settings file's preset, else ``"default"``.
    settings: changes to the preset: a dict of settings keys (``ggs.settings()`` lists them
      all with their values; ``result.settings`` is one), or a TOML/JSON settings file.
    The other arguments change single settings, after ``settings`` (``None``: unchanged);
    each is the settings key of its name (docs/settings.md says what each does):
    rotations: a name of ``ROTATION_SETS``, a ``.npy`` file, or an (N, 3, 3) array of
      rotation matrices; refine: ``"gicp"``, ``"p2plane"``, ``"p2p"`` or ``"none"``;
      kernel: ``"none"``, ``"huber:K"``, ``"cauchy:K"``, ``"geman-mcclure:K"`` (K in cloud
      units); search: ``"exhaustive"`` or ``"coarse-to-fine"``; precision: ``"mixed"`` or
      ``"f64"`` (the same picks); max_hypotheses, margin, verify_score (``"tight"``,
      ``"fitness"``, ``"oriented"``), verify, first_look, polish: the verification;
      top_k: coarse hypotheses reported (of the whole search: no first look);
      distinct_radius, dedup: degrees; max_memory: bytes, or ``"2G"``, ``"512M"``;
      coarse_factor, coarse_keep, coarse_keep_min, coarse_hypotheses: the coarse-to-fine
      search; max_distance, distance_quantile, max_iterations, neighbors, refine_cell: the
      final refinement.
    threads: worker threads (None: all cores); the result does not depend on it.
    progress: called as ``progress(rotations_scored, total)`` while the search runs.

    Returns a :class:`Result` (``result.settings``: every setting in force). Ambiguous or
    low-evidence results issue a :class:`GgsWarning`. Raises ValueError for bad points or
    settings, KeyboardInterrupt on Ctrl-C.
    """
    options, matrices = native_options(
        preset=preset,
        settings=settings,
        rotations=rotations,
        threads=threads,
        voxel=voxel,
        refine=refine,
        kernel=kernel,
        top_k=top_k,
        search=search,
        precision=precision,
        max_hypotheses=max_hypotheses,
        margin=margin,
        verify_score=verify_score,
        verify=verify,
        first_look=first_look,
        polish=polish,
        max_memory=max_memory,
        distinct_radius=distinct_radius,
        dedup=dedup,
        coarse_factor=coarse_factor,
        coarse_keep=coarse_keep,
        coarse_keep_min=coarse_keep_min,
        coarse_hypotheses=coarse_hypotheses,
        max_distance=max_distance,
        distance_quantile=distance_quantile,
        max_iterations=max_iterations,
        neighbors=neighbors,
        refine_cell=refine_cell,
    )
    document, report = _ggs.register(
        as_points(source, "source"),
        as_points(target, "target"),
        options,
        matrices,
        progress,
    )
    return _warn(Result(json.loads(document), report))


def refine(
    source: PointsLike,
    target: PointsLike,
    init: npt.ArrayLike,
    method: Method = "gicp",
    *,
    max_distance: Optional[float] = None,
    distance_quantile: Optional[float] = None,
    max_iterations: Optional[int] = None,
    neighbors: Optional[int] = None,
    kernel: Optional[str] = None,
    threads: Optional[int] = None,
) -> Result:
    """Refine an initial 4×4 transform ``init`` (``p_target = init · p_source``) by ICP,
    with the reference GICP's settings (the ``"paper"`` preset's) changed by the arguments.

    method: ``"gicp"``, ``"p2plane"`` or ``"p2p"``. max_distance: a fixed correspondence
    distance (default: the ``distance_quantile``, 0.25, of the nearest-neighbour distances at
    the start); max_iterations: 500; neighbors (normals and covariances): 20; kernel as in
    :func:`register`. Returns a :class:`Result` (its coarse fields are None).
    """
    given = {
        "refine": method,
        "max_distance": max_distance,
        "distance_quantile": distance_quantile,
        "max_iterations": max_iterations,
        "neighbors": neighbors,
        "kernel": kernel,
    }
    changes = {k: v for k, v in given.items() if v is not None}
    document = _ggs.refine(
        as_points(source, "source"),
        as_points(target, "target"),
        np.ascontiguousarray(init, dtype=np.float64),
        json.dumps(changes, default=_plain),
        _threads(threads),
    )
    return _warn(Result(json.loads(document)))


PairLike = Tuple[Union[PointsLike, StrPath], Union[PointsLike, StrPath]]


def _load(x: Union[PointsLike, StrPath]) -> PointsLike:
    return read_point_cloud(x) if isinstance(x, (str, os.PathLike)) else x


ViewName = Literal["plan", "front", "side"]


def render(
    target: PointsLike,
    source: Optional[PointsLike] = None,
    transformation: Optional[npt.ArrayLike] = None,
    *,
    view: ViewName = "plan",
    size: Tuple[int, int] = (640, 480),
) -> npt.NDArray[np.uint8]:
    """A picture of ``target`` (blue) and ``source`` (orange, moved by ``transformation``
    when given) as an (height, width, 3) uint8 array, for notebooks (``plt.imshow``).

    An orthographic view along the target's principal axes (``"plan"``: the two largest,
    ``"front"``, ``"side"``), nearer points brighter, framed on the points shown; at most
    200 000 points per cloud are drawn (evenly strided). The pictures of
    :meth:`Result.report_html` are made the same way.
    """
    width, height = size
    layers = [(as_points(target, "target"), (40, 110, 230))]
    if source is not None:
        pts = as_points(source, "source")
        if transformation is not None:
            pts = transform_points(pts, transformation)
        layers.append((pts, (245, 130, 20)))
    return _ggs.render_view(layers, view, int(width), int(height))


def _register_loaded(
    src: Union[PointsLike, StrPath],
    tgt: Union[PointsLike, StrPath],
    voxel: Optional[float],
    options: Dict[str, Any],
) -> Result:
    """:func:`register` of a pair given as points or paths (read here: on a Ray worker, the
    worker reads its files), its warnings left to the caller (:func:`_warn`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GgsWarning)
        return register(_load(src), _load(tgt), voxel, **options)


def register_many(
    pairs: Iterable[PairLike],
    voxel: Optional[float] = None,
    *,
    executor: Literal["local", "ray"] = "local",
    retries: int = 3,
    on_error: Literal["raise", "return"] = "raise",
    progress: Optional[Callable[[int, Union[Result, Exception]], None]] = None,
    **options: Any,
) -> List[Union[Result, Exception]]:
    """Register every ``(source, target)`` of ``pairs`` (arrays, point-like objects or file
    paths, read with :func:`read_point_cloud`) with the same options as :func:`register`;
    the results in the order of ``pairs``.

    ``on_error="return"`` puts the exception of a failing pair in its place instead of
    raising; ``progress(index, result_or_error)`` is called after each pair, in the order
    they finish.

    ``executor="ray"`` registers each pair as a Ray task (``ray.init()`` unless Ray is
    already initialized). Give paths, not arrays: each worker reads its own pair's files
    (arrays work, but travel through Ray's object store). Each task reserves ``threads``
    CPUs (default 1) and uses that many threads; a task whose worker died is retried
    ``retries`` times, then its Ray error counts as the pair's error.
    """
    items = list(pairs)
    out: List[Union[Result, Exception, None]] = [None] * len(items)

    def finish(k: int, r: Union[Result, Exception]) -> None:
        if isinstance(r, Exception) and on_error == "raise":
            raise r
        out[k] = _warn(r) if isinstance(r, Result) else r
        if progress is not None:
            progress(k, r)

    if executor == "ray":
        from ._ray import run_tasks

        if options.get("threads") is None:
            options["threads"] = 1
        settings(**{k: v for k, v in options.items() if k != "threads"})  # bad ones fail here
        run_tasks(
            _register_loaded,
            ((k, (src, tgt, voxel, options)) for k, (src, tgt) in enumerate(items)),
            cpus=max(1, int(options["threads"] or 1)),
            retries=retries,
            on_result=finish,
            on_error=lambda k, e: finish(k, _unwrap(e)),
        )
    elif executor == "local":
        for k, (src, tgt) in enumerate(items):
            try:
                r: Union[Result, Exception] = _register_loaded(src, tgt, voxel, options)
            except (ValueError, OSError) as e:
                r = e
            finish(k, r)
    else:
        raise ValueError(f"executor must be 'local' or 'ray', not {executor!r}")
    return [r for r in out if r is not None]


def _unwrap(e: BaseException) -> Exception:
    """The exception a Ray task raised (Ray wraps it), or Ray's own error (a lost worker)."""
    cause = getattr(e, "cause", None)
    if isinstance(cause, Exception):
        return cause
    return e if isinstance(e, Exception) else RuntimeError(str(e))


def read_point_cloud(
    path: StrPath,
    format: Optional[str] = None,
    *,
    scan: Optional[int] = None,
    apply_pose: bool = True,
    array: Optional[str] = None,
    sample_mesh: Optional[int] = None,
) -> Points:
    """Read any format ggs reads (PLY, PCD, XYZ/TXT/CSV/PTS, NPY/NPZ, KITTI .bin, LAS/LAZ,
    E57, OBJ, STL) as an (N, 3) float64 array. E57: ``scan`` picks one scan (default all,
    each moved by its pose unless ``apply_pose=False``); NPZ: ``array`` names the array;
    meshes: ``sample_mesh=N`` samples N points on the faces. A missing file raises
    FileNotFoundError with ``filename`` set; a malformed one ValueError naming the line."""
    return _ggs.read_point_cloud(os.fspath(path), format, scan, apply_pose, array, sample_mesh)


def write_point_cloud(path: StrPath, points: PointsLike, format: Optional[str] = None) -> None:
    """Write (N, 3) points atomically; the format follows the extension (ply, pcd,
    xyz/txt/pts/csv, npy, bin, las, laz, e57) unless given."""
    _ggs.write_point_cloud(os.fspath(path), as_points(points), format)


def rotation_set(name: RotationSetName) -> npt.NDArray[np.float64]:
    """A built-in rotation set as an (N, 3, 3) float64 array."""
    return _ggs.rotation_set(name)


def voxel_downsample(points: PointsLike, voxel: float) -> Points:
    """One point per occupied cell of edge ``voxel`` (cells anchored at the points' minimum):
    the mean of the points in it, in increasing cell order."""
    return _ggs.voxel_downsample(as_points(points), voxel)


def estimate_normals(points: PointsLike, neighbors: int = 20) -> Points:
    """Unit normals (N, 3) from the ``neighbors`` nearest points of each point: the
    eigenvector of the smallest eigenvalue of their covariance (sign arbitrary)."""
    return _ggs.estimate_normals(as_points(points), neighbors)


class Evaluation(NamedTuple):
    """:func:`evaluate`'s figures (Open3D's ``evaluate_registration`` plus the target side)."""

    fitness: float
    """Share of source points within ``max_distance`` of a target point after ``T``."""
    fitness_target: float
    """Share of target points within ``max_distance`` of a moved source point."""
    inlier_rmse: float
    """RMS distance of those source inliers, in the clouds' units."""
    inliers: int


def evaluate(
    source: PointsLike, target: PointsLike, transformation: npt.ArrayLike, max_distance: float
) -> Evaluation:
    """How well ``transformation`` aligns ``source`` onto ``target`` at ``max_distance``."""
    d = _ggs.evaluate(
        as_points(source, "source"),
        as_points(target, "target"),
        np.ascontiguousarray(transformation, dtype=np.float64),
        max_distance,
    )
    return Evaluation(d["fitness"], d["fitness_target"], d["inlier_rmse"], d["inliers"])


def transform_points(points: PointsLike, transformation: npt.ArrayLike) -> Points:
    """``points`` moved by the 4×4 ``transformation``: ``R·p + t`` for every row."""
    p = np.asarray(as_points(points), dtype=np.float64)
    t = np.asarray(transformation, dtype=np.float64)
    if t.shape != (4, 4):
        raise ValueError(f"transformation: expected a 4×4 array, got shape {t.shape}")
    moved: Points = p @ t[:3, :3].T + t[:3, 3]
    return moved


__all__: Sequence[str] = []
