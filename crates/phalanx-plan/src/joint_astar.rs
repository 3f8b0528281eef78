//! Joint-state A* (operator decomposition); written by the joint-search owner.
