MODULE seam
    ! written by hand as in the RAPID reference's examples
    PERS tooldata tNozzle := [TRUE,[[0,0,95],[1,0,0,0]],[0.5,[0,0,40],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata wTable := [FALSE,TRUE,"",[[400,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    CONST speeddata vSeam := [50,500,5000,1000];
    CONST zonedata zSeam := [FALSE,1,1.5,1.5,0.15,1.5,0.15];
    CONST jointtarget jHome := [[0,-30,30,0,45,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    CONST robtarget P1_V1 := [[220,-220,230],[0,1,0,0],[-1,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget SEAM_A := [[320,-20,170],[0,1,0,0],[-1,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    CONST robtarget P7 := [[300,40,160],[0,1,0,0],[0,0,1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    CONST robtarget SEAM_B := [[250,80,150],[0,1,0,0],[0,0,1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];

    PROC main()
        ConfL \Off;
        AccSet 50, 100;
        MoveAbsJ jHome\NoEOffs, v500, fine, tNozzle;
        MoveJ P1_V1, v500, z50, tNozzle\WObj:=wTable;
        MoveL SEAM_A, v100, fine, tNozzle\WObj:=wTable;
        SetDO do1, 1;
        MoveC P7, SEAM_B, vSeam, zSeam, tNozzle\WObj:=wTable;
        MoveL SEAM_A, vSeam\V:=40, z1\Z:=2, tNozzle\WObj:=wTable;
        SetDO do1, 0;
        WaitTime 0.5;
        park;
    ENDPROC

    PROC park()
        MoveAbsJ jHome\NoEOffs, v500, fine, tool0;
    ENDPROC
ENDMODULE
