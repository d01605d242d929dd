"""The worst-case attack search (`ld3 search`), its journal, its report and LD3's analytic bound beside it."""
