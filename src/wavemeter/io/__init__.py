"""Reading and writing measurement tables: columns by name, units, formats."""

from ._reader import ColumnRequest, Table, read_table, table_format, write_table

__all__ = ["ColumnRequest", "Table", "read_table", "table_format", "write_table"]
