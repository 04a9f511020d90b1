"""Checks of the client's operation table and of the requests it sends against the committed
OpenAPI documents (openapi/knowledge.json, openapi/fleet.json)."""

from __future__ import annotations

import email.parser
import email.policy
import json
import re
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema_rs

from mentalsim_client import OPERATIONS, Operation

ROOT = Path(__file__).resolve().parents[3]
OPENAPI = ROOT / "openapi"
METHODS = ("get", "put", "post", "delete", "patch", "head", "options")


@cache
def document(name: str) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((OPENAPI / f"{name}.json").read_text())
    return doc


def resolve(doc: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        ref = schema["$ref"]
        assert ref.startswith("#/"), ref
        node: Any = doc
        for part in ref[2:].split("/"):
            node = node[part]
        schema = node
    return schema


def openapi_operation(op: Operation) -> dict[str, Any] | None:
    item = document(op.document)["paths"].get(op.path)
    if item is None:
        return None
    found: dict[str, Any] | None = item.get(op.method.lower())
    return found


def parameters(op: Operation) -> dict[tuple[str, str], dict[str, Any]]:
    """(in, name lower-cased) -> parameter object, the path item's and the operation's."""
    doc = document(op.document)
    item = doc["paths"][op.path]
    out = {}
    for p in item.get("parameters", []) + (openapi_operation(op) or {}).get("parameters", []):
        p = resolve(doc, p)
        out[(p["in"], p["name"].lower())] = p
    return out


def table_problems(op: Operation) -> list[str]:
    """What of the table's entry for ``op`` the OpenAPI document contradicts."""
    name = f"{op.operation_id} ({op.method} {op.path})"
    spec = openapi_operation(op)
    if spec is None:
        return [f"{name}: no such operation in openapi/{op.document}.json"]
    problems = []
    if spec.get("operationId") != op.operation_id:
        problems.append(f"{name}: the document's operationId is {spec.get('operationId')!r}")
    params = parameters(op)
    in_path = sorted(re.findall(r"\{([^}]+)\}", op.path))
    documented_path = sorted(n for (where, n) in params if where == "path")
    if in_path != documented_path:
        problems.append(f"{name}: path parameters {in_path}, documented {documented_path}")
    for q in op.query:
        if ("query", q.lower()) not in params:
            problems.append(f"{name}: query parameter `{q}` is not documented")
    for h in op.headers:
        if ("header", h.lower()) not in params:
            problems.append(f"{name}: header `{h}` is not documented")
    for (where, n), p in params.items():
        if p.get("required") and where == "query" and n not in [q.lower() for q in op.query]:
            problems.append(f"{name}: required query parameter `{n}` is never sent")
    body = spec.get("requestBody")
    if op.body is None:
        if body is not None and body.get("required"):
            problems.append(f"{name}: the document requires a body the client does not send")
    else:
        content = (body or {}).get("content", {})
        if op.body_type not in content:
            problems.append(f"{name}: no {op.body_type} body documented (documented: {sorted(content)})")
        else:
            ref = content[op.body_type]["schema"].get("$ref", "")
            if ref != f"#/components/schemas/{op.body}":
                problems.append(f"{name}: the body's schema is {ref!r}, the client sends {op.body}")
    ok_types = set()
    for status, response in spec["responses"].items():
        if status.startswith("2"):
            response = resolve(document(op.document), response)
            ok_types |= set(response.get("content", {}))
    for t in op.accept:
        if t not in ok_types:
            problems.append(f"{name}: accepts {t}, a success answers only {sorted(ok_types)}")
    return problems


def match(method: str, raw_path: str) -> Operation | None:
    """The table's operation a request was sent for."""
    for op in OPERATIONS.values():
        pattern = "^" + re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(op.path)) + "$"
        if op.method == method and re.match(pattern, raw_path):
            return op
    return None


def field_problems(doc: dict[str, Any], value: Any, schema: dict[str, Any], where: str) -> list[str]:
    """Readable mismatches of a request body's fields with its schema: fields the schema does not
    have, required fields missing, recursively (``oneOf``: the branch the fields fit)."""
    schema = resolve(doc, schema)
    if "allOf" in schema:
        merged: dict[str, Any] = {"type": "object", "properties": {}, "required": []}
        closed = False
        for part in schema["allOf"]:
            part = resolve(doc, part)
            merged["properties"].update(part.get("properties", {}))
            merged["required"] += part.get("required", [])
            closed = closed or part.get("additionalProperties") is False
        if closed:
            merged["additionalProperties"] = False
        return field_problems(doc, value, merged, where)
    if "oneOf" in schema:
        branches = [resolve(doc, b) for b in schema["oneOf"]]
        if value is None and any(b.get("type") == "null" for b in branches):
            return []
        reports = []
        for b in branches:
            if b.get("type") == "null":
                continue
            p = field_problems(doc, value, b, where)
            if not p:
                return []
            reports.append(p)
        return [f"{where}: fits no branch of oneOf: " + " | ".join("; ".join(r) for r in reports)]
    if isinstance(value, dict) and ("properties" in schema or schema.get("type") == "object"):
        props = schema.get("properties", {})
        problems = []
        if schema.get("additionalProperties") is False:
            for k in value:
                if k not in props:
                    problems.append(f"{where}.{k}: not in the schema")
        for k in schema.get("required", []):
            if k not in value:
                problems.append(f"{where}.{k}: required, not sent")
        for k, v in value.items():
            if k in props:
                sub = props[k]
                enum = resolve(doc, sub).get("enum")
                if enum is not None and v not in enum:
                    problems.append(f"{where}.{k}: {v!r} is not one of {enum}")
                problems += field_problems(doc, v, sub, f"{where}.{k}")
        return problems
    if isinstance(value, list) and "items" in schema:
        out = []
        for i, v in enumerate(value):
            out += field_problems(doc, v, schema["items"], f"{where}[{i}]")
        return out
    return []


@cache
def validator(document_name: str, schema_name: str) -> Any:
    doc = document(document_name)
    return jsonschema_rs.validator_for({"$ref": f"#/components/schemas/{schema_name}", "components": doc["components"]})


def multipart_parts(content_type: str, body: bytes) -> dict[str, bytes]:
    message = email.parser.BytesParser(policy=email.policy.HTTP).parsebytes(
        f"Content-Type: {content_type}\r\n\r\n".encode() + body
    )
    parts = {}
    for part in message.iter_parts():
        name = part.get_param("name", header="content-disposition")
        payload = part.get_payload(decode=True)
        assert isinstance(name, str) and isinstance(payload, bytes)
        parts[name] = payload
    return parts


def request_problems(
    method: str,
    raw_path: str,
    query: dict[str, list[str]],
    headers: dict[str, str],
    content_type: str,
    body: bytes,
    values: bool = True,
) -> tuple[Operation | None, list[str]]:
    """Whether a request the client sent is one of its table's operations, with documented query
    parameters and headers and a body with the fields of its schema; with ``values``, a body
    its schema accepts (bad input sent on purpose has the right fields, not the right values)."""
    op = match(method, raw_path)
    if op is None:
        return None, [f"{method} {raw_path}: not an operation of the client's table"]
    name = f"{op.operation_id} ({method} {raw_path})"
    doc = document(op.document)
    params = parameters(op)
    problems = []
    for q in query:
        if q not in op.query or ("query", q.lower()) not in params:
            problems.append(f"{name}: query parameter `{q}` is not documented")
    for h in headers:
        if h in ("authorization", "accept", "content-type", "content-length", "host", "user-agent", "accept-encoding", "connection"):
            continue
        if ("header", h) not in params:
            problems.append(f"{name}: header `{h}` is not documented")
    accept = headers.get("accept")
    if accept not in op.accept:
        problems.append(f"{name}: Accept {accept!r} is not one of {op.accept}")
    if op.body is None:
        if body:
            problems.append(f"{name}: a body was sent")
        return op, problems
    if not content_type.startswith(op.body_type or ""):
        problems.append(f"{name}: body sent as {content_type!r}, documented {op.body_type}")
        return op, problems
    if op.body_type == "application/json":
        value = json.loads(body)
        problems += [f"{name}: {p}" for p in field_problems(doc, value, {"$ref": f"#/components/schemas/{op.body}"}, "body")]
        errors = [str(e).splitlines()[0] for e in validator(op.document, op.body).iter_errors(value)] if values else []
        if errors:
            problems.append(f"{name}: the body does not validate against {op.body}: {errors[:3]}")
    else:
        parts = multipart_parts(content_type, body)
        schema = resolve(doc, doc["components"]["schemas"][op.body])
        for k in parts:
            if k not in schema.get("properties", {}):
                problems.append(f"{name}: part `{k}` is not in {op.body}")
        for k in schema.get("required", []):
            if k not in parts:
                problems.append(f"{name}: required part `{k}` not sent")
        fields = {k: v.decode("utf-8", "replace") for k, v in parts.items() if k == "name"}
        errors = [str(e).splitlines()[0] for e in validator(op.document, op.body).iter_errors({**{k: "x" for k in parts}, **fields})] if values else []
        if errors:
            problems.append(f"{name}: the parts do not validate against {op.body}: {errors[:3]}")
    return op, problems
