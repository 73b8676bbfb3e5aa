from pinarray.cli import main

raise SystemExit(main())
