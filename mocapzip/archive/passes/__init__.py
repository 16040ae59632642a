"""The passes of `mcz compress` (`archive.writer.compress` runs them in this order), each a
function that takes and gives frozen records:

    check.py         `check`: the settings checked, the clips found, the output refused if it is an input -> `Job`
    first_pass.py    `first_pass`: every clip read once: its row, its skeleton, its class by path, its poses
                     summed (lossless: its stream coded) -> `ClipsRead`
    classes.py       `classes_of`: the units coded (whole clips, --segment's segments) and each one's class -> `Classes`
    class_coding.py  `code_classes` (lossy): each class's basis and its clips' codings, a cut take's segments
                     joined -> `CodedClasses`
    entropy_pass.py  `entropy_pass` (lossy): the clip streams as stored, with the archive's priors where
                     they pay -> `StoredClips`
    write.py         `write`: meta assembled from the records, the skeletons stream, the archive committed -> `Written`

and one `mcz append` (`archive.edit.append`) runs between the classes and the class coding:

    stored_classes.py  `code_in_stored`: each new clip coded in the archive's stored class nearest it
"""
