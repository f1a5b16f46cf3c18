/* The logical types the SQL functions return (functions.h). */
#include "functions.h"

DUCKDB_EXTENSION_EXTERN

duckdb_logical_type mdb_struct_list_type(const char **names, const duckdb_type *ids, size_t n) {
	duckdb_logical_type members[MDB_MAX_STRUCT_MEMBERS];
	n = n < MDB_MAX_STRUCT_MEMBERS ? n : MDB_MAX_STRUCT_MEMBERS;
	for (size_t i = 0; i < n; i++) {
		members[i] = duckdb_create_logical_type(ids[i]);
	}
	duckdb_logical_type s = duckdb_create_struct_type(members, names, n);
	for (size_t i = 0; i < n; i++) {
		duckdb_destroy_logical_type(&members[i]);
	}
	duckdb_logical_type list = duckdb_create_list_type(s);
	duckdb_destroy_logical_type(&s);
	return list;
}
