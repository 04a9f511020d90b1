"""The one exception the client raises for anything the service or the network refused."""

from __future__ import annotations

import json
from typing import Any

import httpx


class MentalsimError(Exception):
    """A request that did not succeed.

    ``status`` is the HTTP status (``None`` when no answer arrived: the service was unreachable
    or the request timed out), ``code`` the API's stable error code (``ErrorBody.error.code``:
    ``not_found``, ``unprocessable``, ``conflict``, ...; ``unreachable`` or ``timeout`` without
    an answer, ``http_<status>`` for an answer that is not an ``ErrorBody``), ``message`` what is
    wrong, ``field`` the request field at fault when one is (a dotted path such as
    ``options.max_attempts``), ``details`` the structured details some errors carry (a plan's attempts, the nearest
    free point), ``request_id`` the service's ``x-request-id`` and ``retry_after`` the seconds
    ``Retry-After`` asks to wait (429, 503).
    """

    def __init__(
        self,
        status: int | None,
        code: str,
        message: str,
        *,
        field: str | None = None,
        details: dict[str, Any] | None = None,
        request_id: str | None = None,
        retry_after: float | None = None,
        operation: str | None = None,
    ) -> None:
        where = f" ({operation})" if operation else ""
        shown = f"{status} {code}" if status is not None else code
        super().__init__(f"{shown}{where}: {message}")
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.details = details
        self.request_id = request_id
        self.retry_after = retry_after
        self.operation = operation

    @classmethod
    def from_response(cls, response: httpx.Response, operation: str | None = None) -> MentalsimError:
        """The error an unsuccessful answer stands for (its body must have been read)."""
        code = f"http_{response.status_code}"
        message = response.reason_phrase or "request failed"
        details: dict[str, Any] | None = None
        field: str | None = None
        try:
            body = json.loads(response.content) if response.content else None
        except ValueError:
            body = None
            text = response.content[:500].decode("utf-8", "replace").strip()
            if text:
                message = text
        if isinstance(body, dict) and isinstance(body.get("error"), dict):
            error = body["error"]
            if isinstance(error.get("code"), str):
                code = error["code"]
            if isinstance(error.get("message"), str):
                message = error["message"]
            if isinstance(error.get("field"), str):
                field = error["field"]
            if isinstance(error.get("details"), dict):
                details = error["details"]
        retry_after: float | None = None
        raw = response.headers.get("retry-after")
        if raw is not None:
            try:
                retry_after = float(raw)
            except ValueError:
                retry_after = None
        return cls(
            response.status_code,
            code,
            message,
            field=field,
            details=details,
            request_id=response.headers.get("x-request-id"),
            retry_after=retry_after,
            operation=operation,
        )

    @classmethod
    def from_transport(cls, error: httpx.TransportError, operation: str | None = None) -> MentalsimError:
        """The error a request that got no answer stands for."""
        code = "timeout" if isinstance(error, httpx.TimeoutException) else "unreachable"
        return cls(None, code, str(error) or type(error).__name__, operation=operation)
