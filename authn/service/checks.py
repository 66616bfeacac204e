"""POST /v1/checks and /v1/checks:batch: the `authn check --json` object over HTTP.

A decision is answered only after its audit entry committed; a failed check is audited as
the CLI audits it. The upload is held in memory (size-limited while it streams, see
limits.py); the recording reader takes a path, so the bytes go to a private temporary file
for the read and nothing else. Nothing is unpickled (the reader refuses pickles)."""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import Annotated, Any, NoReturn

from fastapi import APIRouter, Depends, File, Form, Request, UploadFile
from fastapi import Path as FastPath
from fastapi.responses import JSONResponse, Response

from core.errors import EXIT_BAD_INPUT
from authn.service.auth import Caller
from authn.service.deps import require, runtime

router = APIRouter(prefix="/v1", tags=["checks"])
_ERRORS: dict[int | str, dict[str, Any]] = {
    400: {"description": "bad recorded return"}, 401: {"description": "no valid API key"},
    403: {"description": "role may not check"},
    413: {"description": "upload too large, or a capture naming more drones than the server's --max-drones"},
    415: {"description": "not multipart/form-data"}, 422: {"description": "missing or invalid field"},
    503: {"description": "database or policy engine unavailable; nothing was decided"}}
_TMP = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def _name(upload: UploadFile) -> str:
    """The client's file name (base name only, one line), for the JSON's `file` and the audit."""
    name = Path((upload.filename or "upload").replace("\\", "/")).name
    return " ".join(name.split())[:200] or "upload"


def _read(data: bytes, name: str, header: bool = False) -> Any:
    """The recording in `data` (with `header`, only its `signatures.recording.Header`), read
    through a private temporary file (errors name the upload)."""
    from core.errors import AuthnException
    from signatures.recording import read_header, read_recording

    fd, tmp = tempfile.mkstemp(suffix=".upload", dir=_TMP)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        try:
            return read_header(tmp) if header else read_recording(tmp)
        except AuthnException as exc:  # the message names the file: the client's name, not ours
            exc.args = (str(exc).replace(tmp, name),)
            raise
    finally:
        os.unlink(tmp)


def _input(data: bytes, name: str, serial: str | None, capture: Any = None, sprt: Any = None) -> Any:
    from authn.check import CheckInput

    return CheckInput(name, serial, lambda: (_read(data, name), hashlib.sha256(data).hexdigest()), capture,
                      sprt=sprt)


def _check_one(checker: Any, data: bytes, name: str, serial: str | None, capture: Any = None,
               sprt: Any = None) -> list[Any]:
    """The decisions (one; one per drone heard with a Remote ID capture), recorded before they
    are answered (`Checker.check`); a failure raises as the CLI's does (bad input 400, anything
    else 503)."""
    from authn.check import Failure

    items = checker.check([_input(data, name, serial, capture, sprt)]).items
    if isinstance(items[0], Failure):
        items[0].raise_()
    return items


def _draw(folder: Path, data: bytes, name: str, items: list[Any]) -> None:
    """Each decision's evidence figure (authn.figure) as `<audit id>.png` in `folder`."""
    from authn.figure import draw

    rec = _read(data, name)
    for o in items:
        tmp = folder / f".{o.audit_id}.{os.getpid()}.png"
        draw(rec, o.to_json(), tmp)
        os.replace(tmp, folder / f"{o.audit_id}.png")  # whole or absent, never half written


def _check_many(checker: Any, files: list[tuple[str, bytes]], serial: str | None) -> list[Any]:
    """Every upload decided with the radar stages batched and recorded in one transaction
    (`Checker.check`); a SystemFault stops the batch after recording what it decided."""
    batch = checker.check([_input(data, name, serial) for name, data in files])
    if batch.fault is not None:  # the database or policy engine: the batch cannot go on
        raise batch.fault
    return batch.items


async def _refuse(rt: Any, what: str, serial: str | None, exc: Exception) -> NoReturn:
    """Record a request refused before any check (an audit error entry naming `what`, as a failed
    check is recorded), then raise."""
    from authn.check import Failure

    await rt.run(lambda: rt.checker.record([Failure.of(what, serial, exc)]))
    raise exc


def _serial(serial: str | None) -> str | None:
    """The claimed serial in its normal form (`core.uasid.normalise`); a malformed one is a 422."""
    from fastapi import HTTPException

    from core.uasid import SerialError, normalise

    if serial is None or not serial.strip():
        return None
    try:
        return normalise(serial)
    except SerialError as exc:
        raise HTTPException(422, f"serial: {exc}") from None


@router.post("/checks", responses=_ERRORS, summary="Check one recorded return")
async def check(request: Request, file: Annotated[UploadFile, File(description="HDF5 or .npz recorded return")],
                serial: Annotated[str | None, Form(max_length=64, description="claimed serial")] = None,
                rid_capture: Annotated[UploadFile | None, File(description="pcap/pcapng Remote ID capture "
                                                                           "heard beside the radar")] = None,
                rid_skew: Annotated[float, Form(ge=0.0, le=3600.0, description="capture clock skew, s")] = 2.0,
                figure: Annotated[bool, Form(description="also draw the evidence figure: "
                                                         "GET /v1/checks/{audit_id}/figure.png")] = False,
                false_accept: Annotated[float, Form(gt=0.0, lt=0.5, description="target false-accept rate "
                                                                                "(Wald's alpha; one dwell is a "
                                                                                "track of one)")] = 1e-3,
                false_reject: Annotated[float, Form(gt=0.0, lt=0.5, description="target false-reject rate "
                                                                                "(Wald's beta)")] = 1e-2,
                _caller: Caller = Depends(require("check"))) -> JSONResponse:
    """Decide one return: the `authn check --json` object, status 200 for accept, reject and inconclusive;
    with `rid_capture`, a JSON array when it heard several drones (one decision each)."""
    rt = runtime(request)
    data, name = await file.read(), _name(file)
    capture = None
    if rid_capture is not None:
        from authn.check import RidCapture

        capture = RidCapture.data(_name(rid_capture), await rid_capture.read(), rid_skew, rt.settings.max_drones,
                                  "the server's --max-drones")
    from authn.sprt import Sprt

    sprt = Sprt(false_accept, false_reject)
    claimed = _serial(serial)
    items = await rt.run(lambda: _check_one(rt.checker, data, name, claimed, capture, sprt))
    for o in items:
        rt.metrics.outcome(o.decision, o.reasons, o.timings_ms)
    if figure:  # after the decisions are recorded and counted: a figure never holds one back
        await rt.run(lambda: _draw(rt.settings.figures_folder(), data, name, items))
    return JSONResponse(items[0].to_json() if len(items) == 1 else [o.to_json() for o in items])


@router.get("/checks/{audit_id}/figure.png", response_class=Response, summary="A check's evidence figure",
            responses={**_ERRORS, 404: {"description": "no figure for that check"},
                       200: {"content": {"image/png": {}}, "description": "the PNG"}})
async def check_figure(request: Request, audit_id: Annotated[int, FastPath(ge=1, le=2**62)],
                       _caller: Caller = Depends(require("read_audit"))) -> Response:
    """The evidence figure of check `audit_id`, drawn when it was posted with `figure=true`
    (docs/policies.md, "A picture of a decision")."""
    from fastapi import HTTPException

    path = runtime(request).settings.figures_folder() / f"{audit_id}.png"
    try:
        png = path.read_bytes()
    except FileNotFoundError:
        raise HTTPException(404, f"no figure for check {audit_id}: post the check with figure=true") from None
    return Response(png, media_type="image/png")


@router.post("/checks:batch", responses=_ERRORS, summary="Check several recorded returns")
async def check_batch(request: Request,
                      files: Annotated[list[UploadFile], File(description="HDF5 or .npz recorded returns")],
                      serial: Annotated[str | None, Form(max_length=64, description="claimed serial for all")] = None,
                      _caller: Caller = Depends(require("check"))) -> JSONResponse:
    """Decide several returns in one audit transaction: `results` holds, per file in order, the
    `authn check --json` object or `{"file", "error", "exit_code"}`."""
    from authn.check import Outcome

    rt = runtime(request)
    if len(files) > rt.settings.max_batch_files:  # a decision per file: refused, audited, before any is read
        from core.errors import OverLimit

        limit = rt.settings.max_batch_files
        await _refuse(rt, "checks:batch", _serial(serial),
                      OverLimit(f"{len(files)} files in one batch, more than the limit of {limit} decisions per "
                                "request (send several batches)"))
    loaded = [(_name(f), await f.read()) for f in files]
    claimed = _serial(serial)
    items = await rt.run(lambda: _check_many(rt.checker, loaded, claimed))
    for o in items:
        if isinstance(o, Outcome):
            rt.metrics.outcome(o.decision, o.reasons, o.timings_ms)
        else:
            rt.metrics.error(400 if o.exit_code == EXIT_BAD_INPUT else 503, "batch-item")
    return JSONResponse({"results": [o.to_json() for o in items]})


def _decide_track(checker: Any, files: list[tuple[str, bytes]], serial: str | None, false_accept: float,
                  false_reject: float) -> Any:
    """The uploads as one track (`authn.track.check_track`): validated from their headers, then
    decided dwell by dwell and recorded as one audit entry before it is answered."""
    from authn.track import Dwell, Sprt, check_track

    dwells = [Dwell(name, lambda d=data, n=name: _read(d, n, header=True), _input(data, name, None).load)
              for name, data in files]
    return check_track(checker, dwells, serial, Sprt(false_accept, false_reject))


@router.post("/checks:track", responses=_ERRORS, summary="Decide one target's track of dwells")
async def check_track(request: Request,
                      files: Annotated[list[UploadFile], File(description="the dwells (HDF5 or .npz), in time order")],
                      serial: Annotated[str | None, Form(max_length=64, description="claimed serial")] = None,
                      false_accept: Annotated[float, Form(gt=0.0, lt=0.5, description="target false-accept rate "
                                                                                       "(Wald's alpha)")] = 1e-3,
                      false_reject: Annotated[float, Form(gt=0.0, lt=0.5, description="target false-reject rate "
                                                                                       "(Wald's beta)")] = 1e-2,
                      _caller: Caller = Depends(require("check"))) -> JSONResponse:
    """One decision over the dwells of one target with one claim (docs/tracks.md): the
    `authn check --track --json` object, status 200 for any decision; 400 for an empty,
    mixed (waveforms, claims) or out-of-order track."""
    rt = runtime(request)
    if len(files) > rt.settings.max_batch_files:
        from core.errors import AuthnError

        raise AuthnError(f"at most {rt.settings.max_batch_files} dwells per track, got {len(files)}")
    loaded = [(_name(f), await f.read()) for f in files]
    claimed = _serial(serial)
    out = await rt.run(lambda: _decide_track(rt.checker, loaded, claimed, false_accept, false_reject))
    rt.metrics.outcome(out.decision, out.reasons, out.timings_ms)
    return JSONResponse(out.to_json())
