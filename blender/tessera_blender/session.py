# SPDX-License-Identifier: Apache-2.0
"""One render on the farm: a background thread talks to the farm, the main thread owns bpy.

The thread (RenderSession._run) opens tessera.Farm, submits the exported scene and iterates
job.frames(); everything it learns (job id, progress, finished frames, the end, errors) goes into
a queue.Queue as events. The main thread drains that queue in poll(): from the modal operator's
window-manager timer in the UI, or from a loop in execute() in background mode. Frames are loaded
as images and written to disk in the main thread; the thread waits for that before it takes the
next frame, so the package acknowledges a frame to the coordinator only once it is on disk.

Cancelling (Esc, the panel's Cancel button, Blender aborting the modal operator) calls
job.cancel() on a short-lived thread (a gRPC call must not freeze the UI); the frames stream then
ends with tessera.JobCancelled.
"""

import inspect
import os
import queue
import shutil
import tempfile
import threading
import time

import bpy

from . import export, farm_package, frames, images

_sessions = set()  # sessions whose thread may still run (unregister stops them)


class UserError(Exception):
    """Something to report as {'ERROR'} with this message, never a traceback."""


def describe_farm_error(e):
    """The farm's message (FarmError.message), with what was being done and the gRPC status."""
    text = str(e)
    message = getattr(e, "message", None)
    code = getattr(getattr(e, "code", None), "name", None)
    if message and message not in text:
        text = f"{text}: {message}" if text else message
    if code and code not in text:
        text = f"{code}: {text}"
    return text or type(e).__name__


class Progress:
    def __init__(self):
        self.tiles_done = self.tiles_total = 0
        self.frames_done = self.frames_total = 0
        self.mrays_per_s = 0.0
        self.estimated_rmse = None
        self.state = "submitting"

    def update(self, p):
        for k in ("tiles_done", "tiles_total", "frames_done", "frames_total", "mrays_per_s", "estimated_rmse", "state"):
            v = getattr(p, k, None)
            if v is not None:
                setattr(self, k, v)

    def fraction(self):
        return self.tiles_done / self.tiles_total if self.tiles_total else 0.0


class RenderSession:
    """Export (in the constructor, main thread), then start() the farm thread and poll()."""

    def __init__(self, context, export_path=""):
        scene = context.scene
        st = scene.tessera
        self.settings = dict(
            address=st.address.strip(), quality=st.quality, spp=st.spp,
            target_rmse=float(f"{st.target_rmse:.6g}"),  # Blender keeps float32: 0.03, not 0.0299999993
            priority=st.priority, timeout=st.timeout, load_images=st.load_images, write_files=st.write_files)
        if not self.settings["address"]:
            raise UserError("Tessera: set the coordinator address (HOST:PORT) in Render Properties > Tessera farm")
        try:  # what Blender alone can tell first: no farm, no package needed
            export.check_camera(scene)
            frames.frame_range(st.frames, scene.frame_start, scene.frame_end, scene.frame_current)
        except (export.ExportError, frames.FrameError) as e:
            raise UserError(f"Tessera: {e}") from None

        from . import prefs

        try:
            self.tessera = farm_package.import_tessera(prefs.preference_path(context))
        except farm_package.FarmPackageError as e:
            raise UserError(f"Tessera: {e}") from None
        self.token = None
        if st.token_file.strip():
            path = bpy.path.abspath(st.token_file.strip())
            try:
                self.token = self.tessera.read_token_file(path)
            except OSError as e:  # missing or unreadable
                raise UserError(f"Tessera: token file {path}: {e.strerror or e}") from None
            except Exception as e:  # empty
                raise UserError(f"Tessera: token file {path}: {e}") from None

        self._tmpdir = None
        if export_path:
            path = os.path.abspath(bpy.path.abspath(export_path))
        else:
            self._tmpdir = tempfile.mkdtemp(prefix="tessera-blender-")
            path = os.path.join(self._tmpdir, _safe_name(scene.name) + ".glb")
        try:
            self.export = export.export_scene(context, path, st.frames)
        except export.ExportError as e:
            self._remove_export()
            raise UserError(f"Tessera: {e}") from None
        except Exception as e:  # the exporter's own failures: a report, not a traceback
            self._remove_export()
            raise UserError(f"Tessera: glTF export failed: {type(e).__name__}: {e}") from None
        # Recorded with the job (Farm.submit(output=...)): `tessera collect` writes the frames
        # there too, so they land in Blender's output folder even after Blender has closed.
        self.output_pattern = None
        if self.settings["write_files"] and "output" in inspect.signature(self.tessera.Farm.submit).parameters:
            self.output_pattern = images.output_pattern(scene)
        blend = os.path.splitext(os.path.basename(bpy.data.filepath))[0] if bpy.data.filepath else "untitled"
        self.job_name = f"{blend} / {scene.name}"

        self.queue = queue.Queue()
        self.progress = Progress()
        self.job_id = None
        self.state = "submitting"   # submitting, running, done, cancelled, failed
        self.end_message = None     # the farm's message for cancelled / failed
        self.images = {}            # Blender frame -> image name
        self.written = {}           # Blender frame -> EXR path
        self.warnings = list(self.export.warnings)
        self._job = None
        self._lock = threading.Lock()
        self._cancel_requested = False
        self._stop = threading.Event()
        self._thread = None
        self._last_print = 0.0

    # --- main thread ---------------------------------------------------------------------

    def start(self):
        self._thread = threading.Thread(target=self._run, name="tessera-farm", daemon=True)
        _sessions.add(self)
        self._thread.start()

    @property
    def finished(self):
        return self.state in ("done", "cancelled", "failed")

    def poll(self, context):
        """Handles every queued event; True once the job has ended (state says how)."""
        while not self.finished:
            try:
                kind, payload = self.queue.get_nowait()
            except queue.Empty:
                break
            if kind == "submitted":
                self.job_id = payload
                self.state = "running"
                try:
                    context.scene.tessera.last_job_id = payload
                except Exception:
                    pass
            elif kind == "progress":
                self.progress.update(payload)
            elif kind == "frame":
                frame, ack = payload
                try:
                    self._take_frame(context, frame)
                except Exception as e:  # e.g. the output folder is not writable
                    # Stop before releasing the thread: the frame is not acknowledged (the
                    # coordinator keeps it), and the job is cancelled like any other end.
                    self._fail(f"Tessera: frame {frame.index}: {type(e).__name__}: {e}; the render stops "
                               f"(job {self.job_id} is cancelled if still running)")
                    self._stop.set()
                    ack.set()
                    self.cancel()
                    break
                ack.set()
            elif kind == "done":
                self.state = "done"
            elif kind == "cancelled":
                self.state, self.end_message = "cancelled", payload
            elif kind in ("failed", "error"):
                self._fail(payload)
            elif kind == "warning":
                self.warnings.append(payload)
        if self.finished:
            self._stop.set()
            _sessions.discard(self)
        return self.finished

    def _fail(self, message):
        self.state, self.end_message = "failed", message

    def _take_frame(self, context, frame):
        b = frames.tessera_to_blender(int(frame.index))
        image = images.load_frame(self.job_id, b, frame.rgb)
        try:
            if self.settings["write_files"]:
                self.written[b] = images.write_exr(context.scene, image, b)
        finally:
            if self.settings["load_images"]:
                self.images[b] = image.name
                _show_in_image_editors(context, image)
            else:
                bpy.data.images.remove(image)
        self.progress.frames_done = max(self.progress.frames_done, len(self.written) or len(self.images))

    def cancel(self):
        """Asks the farm to cancel the job (now, or as soon as it has an id)."""
        with self._lock:
            already = self._cancel_requested
            self._cancel_requested = True
            job = self._job
        if job is not None and not already:
            threading.Thread(target=self._cancel_on_farm, args=(job,), name="tessera-cancel", daemon=True).start()

    @property
    def cancel_requested(self):
        return self._cancel_requested

    def shutdown(self):
        """Stops waiting on the farm (Blender quits, the add-on is disabled, another file loads).
        A job whose output was recorded keeps rendering: `tessera collect` writes its frames to
        the output folder. Any other job is cancelled (nobody would take its frames)."""
        if not self.finished:
            if self.output_pattern and self.job_id and not self._cancel_requested:
                print(f"Tessera: job {self.job_id} keeps rendering on the farm; `tessera collect` writes its "
                      f"frames to {self.output_pattern} (`tessera cancel {self.job_id}` stops it)")
            else:
                self.cancel()
        self._stop.set()
        _sessions.discard(self)

    def status_text(self):
        p = self.progress
        job = self.job_id or "..."
        if self.state == "submitting":
            return f"Tessera: submitting to {self.settings['address']}"
        text = f"Tessera job {job}: {p.tiles_done}/{p.tiles_total} tiles"
        if p.frames_total:
            text += f", {p.frames_done}/{p.frames_total} frames"
        if p.mrays_per_s:
            text += f", {p.mrays_per_s:.1f} Mrays/s"
        if self._cancel_requested and not self.finished:
            text += " (cancelling)"
        return text

    def print_progress(self, every_s=2.0, force=False):
        now = time.monotonic()
        if force or now - self._last_print >= every_s:
            self._last_print = now
            print(self.status_text(), flush=True)

    def summary(self):
        """(level, message) for the operator's report once finished."""
        if self.state == "done":
            n = len(self.written) or len(self.images)
            where = ""
            if self.written:
                first = self.written[min(self.written)]
                where = f" to {os.path.dirname(first)}" if len(self.written) > 1 else f" to {first}"
            return "INFO", f"Tessera job {self.job_id}: {n} frame{'s' if n != 1 else ''} done{where}"
        if self.state == "cancelled":
            kept = f", {len(self.written) or len(self.images)} finished frames kept" if self.written or self.images else ""
            return "WARNING", f"Tessera job {self.job_id}: cancelled{kept}"
        return "ERROR", self.end_message or "Tessera: the job failed"

    # --- farm thread ---------------------------------------------------------------------

    def _put(self, kind, payload=None):
        self.queue.put((kind, payload))

    def _run(self):
        t = self.tessera
        s = self.settings
        ex = self.export
        try:
            kwargs = dict(frames=frames.submit_frames(ex.first, ex.last), width=ex.width, height=ex.height,
                          priority=s["priority"], camera=ex.camera, name=self.job_name, fps=ex.fps)
            if self.output_pattern:
                kwargs["output"] = self.output_pattern
            if s["quality"] == "TARGET":
                kwargs["target_rmse"] = s["target_rmse"]
            else:
                kwargs["spp"] = s["spp"]
            with t.Farm(s["address"], token=self.token, timeout=s["timeout"]) as farm:
                job = farm.submit(ex.path, **kwargs)
                with self._lock:
                    self._job = job
                    cancel_now = self._cancel_requested
                self._put("submitted", job.id)
                self._remove_export()
                if cancel_now:
                    self._cancel_on_farm(job)
                for frame in job.frames(progress=lambda p: self._put("progress", p)):
                    ack = threading.Event()
                    self._put("frame", (frame, ack))
                    while not ack.wait(0.1):
                        if self._stop.is_set():
                            return
                    if self._stop.is_set():
                        return
                self._put("done")
        except t.JobCancelled as e:
            self._put("cancelled", getattr(e, "message", None) or str(e))
        except t.JobFailed as e:
            self._put("failed", f"Tessera: {describe_farm_error(e)}")
        except t.FarmError as e:
            hint = ""
            if getattr(getattr(e, "code", None), "name", "") == "UNAUTHENTICATED":
                hint = " (in Blender: the Token file in Render Properties > Tessera farm)"
            self._put("error", f"Tessera: {describe_farm_error(e)}{hint}")
        except (ValueError, OSError) as e:  # the package's checks of what was asked (address, files)
            self._put("error", f"Tessera: {e}")
        except Exception as e:  # anything else still ends as a report, never a traceback
            if os.environ.get("TESSERA_BLENDER_DEBUG"):
                import traceback

                traceback.print_exc()
            self._put("error", f"Tessera: {type(e).__name__}: {e}")
        finally:
            self._remove_export()

    def _cancel_on_farm(self, job):
        try:
            job.cancel()
        except Exception as e:
            self._put("warning", f"Tessera: cancelling job {job.id}: {describe_farm_error(e)}")

    def _remove_export(self):
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._tmpdir = None


def _show_in_image_editors(context, image):
    """The newest frame in every open Image Editor (UI only)."""
    wm = getattr(context, "window_manager", None)
    if bpy.app.background or wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = image
                area.tag_redraw()


def _safe_name(name):
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return keep or "scene"


def shutdown_all():
    for s in list(_sessions):
        s.shutdown()


def active_session():
    """The session whose job is still going, if any (the panel shows it)."""
    for s in _sessions:
        if not s.finished:
            return s
    return None
