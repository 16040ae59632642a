"""Getting clips in: the input formats, each declared once (`registry`: suffixes, skeleton text,
reader, writer), which files are clips and which skeleton each pairs with (`discover`), a clip
loaded in its representation and scored against a decode (`clip`), glitches in the source
(`glitches`), and `mcz inspect` (`inspect`). Parsers of the file formats themselves live in
`mocapzip.formats` (formats/)."""
