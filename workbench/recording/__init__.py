"""Everything Rerun: opening a stream, properties, columnar drawing helpers, reading back."""
