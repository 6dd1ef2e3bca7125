#!/usr/bin/env python3
"""Checks live answers of linerwatch-server against its own OpenAPI document.

usage: validate_openapi.py OPENAPI.json EXCHANGES.json

EXCHANGES.json is what test_server_openapi.cpp recorded: a list of
  {"method": "get", "path": "/api/v1/crushers/{crusher}" (the operation's template, or null for a
   request no operation has), "url": what was asked, "status": 200, "content_type": "application/json",
   "body": the body as text, "request": the JSON body sent (optional)}

Each answer must have a status its operation declares, a media type declared for that status, and
a JSON body that validates against the declared schema (jsonschema, Debian's python3-jsonschema);
a request body sent to a 2xx answer must validate against the operation's requestBody. A request
no operation has must be answered with components/schemas/Error. Every operation must be called
at least once with its success status, and no JSON schema in the document may be an object that
says nothing (no properties, additionalProperties, allOf/anyOf or $ref). Prints each failure and
exits 1 when there is any.
"""
import copy
import json
import sys

import jsonschema

OK_PREFIX = "2"


def resolve(node, doc):
    """`node` with every local $ref replaced by what it points to (the document has no cycles)."""
    if isinstance(node, dict):
        if "$ref" in node:
            target = doc
            for part in node["$ref"].lstrip("#/").split("/"):
                target = target[part]
            return resolve(target, doc)
        return {k: resolve(v, doc) for k, v in node.items()}
    if isinstance(node, list):
        return [resolve(v, doc) for v in node]
    return node


def from_openapi(schema):
    """An OpenAPI 3.0 schema as JSON Schema: `nullable: true` becomes a type (or alternative) null."""
    if isinstance(schema, list):
        return [from_openapi(s) for s in schema]
    if not isinstance(schema, dict):
        return schema
    out = {}
    for key, value in schema.items():
        if key in ("properties", "patternProperties"):
            out[key] = {name: from_openapi(s) for name, s in value.items()}
        elif key in ("items", "additionalProperties", "not") or key in ("allOf", "anyOf", "oneOf"):
            out[key] = from_openapi(value)
        else:
            out[key] = copy.deepcopy(value)
    if out.pop("nullable", False):
        if "type" in out:
            out["type"] = [out["type"], "null"]
            if "enum" in out:
                out["enum"] = list(out["enum"]) + [None]
        else:
            return {"anyOf": [out, {"type": "null"}]}
    return out


def vague_objects(schema, where, found):
    """Appends to `found` the places where an object schema says nothing about its members."""
    if isinstance(schema, list):
        for i, s in enumerate(schema):
            vague_objects(s, "%s[%d]" % (where, i), found)
        return
    if not isinstance(schema, dict):
        return
    says = any(k in schema for k in ("properties", "additionalProperties", "allOf", "anyOf", "oneOf", "$ref"))
    if schema.get("type") == "object" and not says:
        found.append(where)
    for key in ("properties",):
        for name, s in schema.get(key, {}).items():
            vague_objects(s, where + "." + name, found)
    for key in ("items", "additionalProperties", "allOf", "anyOf", "oneOf"):
        if key in schema:
            vague_objects(schema[key], where + "." + key, found)


def json_schemas(doc):
    """(where, schema) of every JSON body schema in the document."""
    for path, ops in doc["paths"].items():
        for method, op in ops.items():
            body = op.get("requestBody", {}).get("content", {}).get("application/json")
            if body:
                yield "%s %s request" % (method, path), body["schema"]
            for status, response in op["responses"].items():
                media = response.get("content", {}).get("application/json")
                if media:
                    yield "%s %s %s" % (method, path, status), media["schema"]
    for name, schema in doc.get("components", {}).get("schemas", {}).items():
        yield "components.schemas." + name, schema


def check(schema, instance, what, doc, failures):
    # Formats (date-time) are checked where jsonschema has their checker (rfc3339-validator installed).
    validator = jsonschema.Draft4Validator(from_openapi(resolve(schema, doc)),
                                           format_checker=jsonschema.Draft4Validator.FORMAT_CHECKER)
    for error in sorted(validator.iter_errors(instance), key=lambda e: list(e.absolute_path)):
        where = "/".join(str(p) for p in error.absolute_path) or "(body)"
        failures.append("%s: at %s: %s" % (what, where, error.message[:300]))


def check_exchange(x, doc, failures, called):
    what = "%s %s -> %d" % (x["method"].upper(), x["url"], x["status"])
    media_type = x["content_type"].split(";")[0].strip()
    if x["path"] is None:
        if media_type != "application/json":
            failures.append("%s: answered %s, not the error body" % (what, media_type))
            return
        check(doc["components"]["schemas"]["Error"], json.loads(x["body"]), what, doc, failures)
        return
    op = doc["paths"].get(x["path"], {}).get(x["method"])
    if op is None:
        failures.append("%s: the document has no operation %s %s" % (what, x["method"], x["path"]))
        return
    response = op["responses"].get(str(x["status"]))
    if response is None:
        failures.append("%s: status %d is not declared (declared: %s)" % (what, x["status"], ", ".join(op["responses"])))
        return
    content = response.get("content", {})
    if media_type not in content:
        failures.append("%s: media type %s is not declared for %d (declared: %s)" %
                        (what, media_type, x["status"], ", ".join(content)))
        return
    if str(x["status"]).startswith(OK_PREFIX):
        called.add((x["method"], x["path"]))
        if "request" in x and "requestBody" in op:
            check(op["requestBody"]["content"]["application/json"]["schema"], x["request"], what + " (request)", doc,
                  failures)
    if media_type == "application/json":
        try:
            body = json.loads(x["body"])
        except ValueError as e:
            failures.append("%s: the body is not JSON: %s" % (what, e))
            return
        check(content[media_type]["schema"], body, what, doc, failures)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        doc = json.load(f)
    with open(sys.argv[2]) as f:
        exchanges = json.load(f)
    failures = []
    vague = []
    for where, schema in json_schemas(doc):
        vague_objects(schema, where, vague)
    failures += ["%s: an object schema that says nothing of its members" % v for v in vague]
    called = set()
    for x in exchanges:
        check_exchange(x, doc, failures, called)
    for path, ops in doc["paths"].items():
        for method in ops:
            if (method, path) not in called:
                failures.append("%s %s: never called with a success status" % (method.upper(), path))
    statuses = sorted({(x["method"].upper() + " " + str(x["path"]), x["status"]) for x in exchanges})
    print("%d answers checked, %d operations called, %d distinct (operation, status) pairs" %
          (len(exchanges), len(called), len(statuses)))
    for op, status in statuses:
        print("  %s %d" % (op, status))
    for f in failures:
        print("FAIL " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
