"""JSON Schema building blocks that meta's schema (`archive.meta.SCHEMA`) and the input formats'
own fields in meta (`inputs.registry.InputFormat.row_schema`, `entry_schema`) share."""

NEWLINE = {"enum": ["\n", "\r\n", "\r"]}


def record(required: dict, optional: dict | None = None) -> dict:
    """An object with exactly these fields: unknown ones are refused, not ignored."""
    return {"type": "object", "required": list(required), "additionalProperties": False,
            "properties": {**required, **(optional or {})}}
