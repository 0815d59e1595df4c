"""The errors of the bag readers (bench_engine.bag_reader, bench_engine.mcap_records, bench_engine.columns,
bench_engine.recovery), in one place.

Every reader turns whatever is wrong with a bag into one of these, with a one-line message naming the file
(or the topic) and what is wrong; no library error (zstd, lz4, struct, mcap's, rclpy's) leaves a reader::

    ValueError
    └── BagError               anything that stops a bag being read: catch this one
        ├── BagDamaged         the bytes are not an intact bag: truncated, a length or offset past the end of
        │   │                  the file or of its record, a claimed size beyond the reader's limits, a CRC
        │   │                  that does not match, data that does not decompress, metadata.yaml unreadable
        │   ├── MessageDamaged one message's CDR bytes do not hold a message of its type (bench_engine.columns,
        │   │                  BagReader.decoded)
        │   └── BagUnrecoverable  recovery found nothing to rebuild from (no .mcap file, no readable header)
        └── BagUnsupported     an intact bag the bench does not read: storage other than MCAP, a message type
                               that is not installed or has no columnar layout

The classes are ValueErrors, as the readers raised before they had their own. This module imports nothing, so
the lowest reader (bench_engine.columns) can raise them too.
"""

from __future__ import annotations


class BagError(ValueError):
    """A bag cannot be read; the message names the file or topic and what is wrong."""


class BagDamaged(BagError):
    """A bag's bytes are not an intact bag (truncated or corrupt)."""


class MessageDamaged(BagDamaged):
    """A message's CDR bytes do not hold a message of its type."""


class BagUnrecoverable(BagDamaged):
    """The directory holds no MCAP file, or not even its header could be read."""


class BagUnsupported(BagError):
    """An intact bag that holds something the bench does not read (storage, message type)."""
